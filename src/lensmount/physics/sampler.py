"""Random numbers keyed by what they are for, never by how the work was split.

Two kinds, both pure functions of their keys:

- `stream(seed, purpose, index)`: a numpy Generator for one job (a pilot, a test).
- `Streams(seed, purpose, keys, step)`: counter-based numbers for a batch of paths. Draw `dim`
  of path i at step `step` is a hash (splitmix64) of (seed, purpose, key_i, step, dim). A photon
  keyed by its global index in the run therefore draws the same numbers at every bounce
  whichever pass, batch or worker traces it and whatever other photons share its batch:
  forward results for the same total photons are identical however they are split.

`Streams.random(size)` and `Streams.choice(a, size, p)` draw the next dimensions for every path
of the batch (the calls a source's `emit` makes); `Streams.at(rows, dim)` draws one named
dimension for some rows (the tracer's Fresnel branch, a BSDF sample, roulette).
"""

from __future__ import annotations

import zlib

import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def stream(seed: int, purpose: str, index: int = 0) -> np.random.Generator:
    """An independent generator for (run seed, purpose, index); `purpose` names the use ("pilot", "test")."""
    if int(seed) < 0 or int(index) < 0:
        raise ValueError(f"seed and index must be >= 0, got seed={seed}, index={index}")
    key = [int(seed), zlib.crc32(purpose.encode()), int(index)]
    return np.random.Generator(np.random.Philox(np.random.SeedSequence(key)))


def _mix(z: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser: a bijection of uint64 that scrambles every bit."""
    with np.errstate(over="ignore"):
        z = (z ^ (z >> np.uint64(30))) * _M1
        z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def _combine(h: np.ndarray, x) -> np.ndarray:
    with np.errstate(over="ignore"):
        return _mix(h ^ (np.asarray(x).astype(np.uint64) + _GOLDEN))


def _u64(value: int) -> np.ndarray:
    return np.asarray(int(value) & 0xFFFFFFFFFFFFFFFF, dtype=np.uint64)


class Streams:
    """Counter-based uniform numbers for a batch of N paths (see the module docstring).

    Args:
        seed: run seed (>= 0).
        purpose: what the numbers are for ("forward", "photons", "view-map"), hashed into the key.
        keys: one int array (N,) or a tuple of int arrays broadcast to (N,): each path's identity,
            e.g. (global photon index,) or (pass, pixel, sample).
        step: the path's step (bounce) these numbers belong to.
    """

    def __init__(self, seed: int, purpose: str, keys, step: int = 0):
        if int(seed) < 0:
            raise ValueError(f"seed must be >= 0, got {seed}")
        parts = keys if isinstance(keys, tuple) else (keys,)
        parts = np.broadcast_arrays(*[np.asarray(k, dtype=np.int64) for k in parts])
        h = _mix(_u64(seed) ^ _GOLDEN)
        h = _combine(h, zlib.crc32(purpose.encode()))
        for k in parts:
            if np.any(k < 0):
                raise ValueError("path keys must be >= 0")
            h = _combine(h, k)
        self._key = np.ascontiguousarray(_combine(h, int(step)).reshape(-1))
        self._next_dim = 0

    @classmethod
    def _from_key(cls, key: np.ndarray) -> "Streams":
        s = cls.__new__(cls)
        s._key, s._next_dim = key, 0
        return s

    @classmethod
    def from_generator(cls, rng: np.random.Generator, n: int) -> "Streams":
        """Streams for callers that hold a Generator (tests, one-off tools): one random key per path."""
        return cls._from_key(_mix(rng.integers(0, 2**63, size=int(n), dtype=np.int64).astype(np.uint64)))

    def __len__(self) -> int:
        return len(self._key)

    def take(self, rows) -> "Streams":
        """The streams of some paths (bool mask or indices); they keep their numbers."""
        return Streams._from_key(self._key[rows])

    @property
    def keys(self) -> np.ndarray:
        """(N,) uint64 the paths' keys, for compiled code that draws `at` itself (not to be modified)."""
        return self._key

    def at(self, rows, dim) -> np.ndarray:
        """(len(rows),) uniforms in [0, 1) of dimension `dim` (an int, or one per row) for paths
        `rows` (None: all)."""
        key = self._key if rows is None else self._key[rows]
        h = _combine(key, np.asarray(dim, np.int64))
        return (h >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)

    def random(self, size=None) -> np.ndarray:
        """Generator-style: (N,) or (N, d) uniforms, the next d dimensions of every path."""
        n = len(self._key)
        shape = (n,) if size is None else ((size,) if np.isscalar(size) else tuple(size))
        if shape[0] != n:
            raise ValueError(f"Streams of {n} paths asked for {shape[0]} rows")
        d = int(np.prod(shape[1:])) if len(shape) > 1 else 1
        u = np.stack([self.at(None, self._next_dim + j) for j in range(d)], axis=1)
        self._next_dim += d
        return u.reshape(shape)

    def choice(self, a: int, size=None, p=None) -> np.ndarray:
        """Generator-style: one index in range(a) per path, with probabilities p (uniform when None)."""
        u = self.random(size if size is not None else len(self._key))
        p = np.full(int(a), 1.0 / int(a)) if p is None else np.asarray(p, np.float64) / np.sum(p)
        return np.minimum(np.searchsorted(np.cumsum(p), u, side="right"), int(a) - 1)


def ray_streams(rng, n: int) -> Streams:
    """The per-ray streams a tracer call draws from: `rng` itself when it is Streams for these n
    rays, else keys drawn from the Generator (callers outside the integrators)."""
    if isinstance(rng, Streams):
        if len(rng) != n:
            raise ValueError(f"Streams of {len(rng)} paths for a batch of {n} rays")
        return rng
    return Streams.from_generator(rng if rng is not None else np.random.default_rng(0), n)


__all__ = ["stream", "Streams", "ray_streams"]
