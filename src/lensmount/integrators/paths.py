"""Path signatures: the ordered non-specular events of every deposit, down to the CAD face.

An optics engineer asks "where does this stray light come from?" in the words of the CAD:
"sun → lens-2 edge (face 3) → spacer-1 bore (face 1) → detector". Every deposit of a pass
carries that sequence as one int64, its *signature*:

- codes: a scatter at mesh tag t (one CAD face of one part, `cad.mesh.FaceTag`) is code t ≥ 0;
  a stretch of propagation with n Fresnel (ghost) reflections, the first two at prescription
  surfaces i and j (0-based; j = −1 for one), is code `ghost_code(n, i, j)` < 0 (`ghost_of` decodes);
- `signature_of(parent, code)`: a 64-bit hash of (parent signature, code), built as the photons
  walk, one vectorised call per event; the empty path (the direct image) is `EMPTY` = 0.

The side table `events` (signature → codes) gets one entry per distinct (parent, code) pair: a
Python loop over distinct paths (tens to thousands), never over photons. Two paths share a
signature only by a 64-bit hash collision (p ≈ K²/2⁶⁵ for K paths).

`PathTally` is one pass's per-signature detector irradiance (flux and a binned image);
`FaceTally` is one pass's per-face light: the flux photons bring to each face (illuminated) and
the étendue with which the detector sees it (critical, from the view map's backward samples).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

EMPTY = 0
PATH_IMAGE_MAX = 120  # per-path and per-face images are binned to at most this many pixels a side
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1, _M2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
_CODE_OFFSET = np.uint64(1 << 32)  # codes ≥ −2³² stay distinct after the shift


_SURFACES = 1024  # prescription surfaces a ghost code can name


def ghost_code(reflections: np.ndarray, first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """(N,) code of a propagation stretch with n ≥ 1 Fresnel reflections, the first two at surfaces
    `first` and `second` (0-based prescription indices, −1 none): −(1 + (i+1) + S (j+1) + S² min(n, 63))."""
    n = np.minimum(np.asarray(reflections, np.int64), 63)
    return -(1 + (np.asarray(first, np.int64) + 1) + _SURFACES * (np.asarray(second, np.int64) + 1)
             + _SURFACES * _SURFACES * n)


def ghost_of(code: int) -> tuple[int, int, int]:
    """(reflections, first surface, second surface) of a ghost code (surfaces 0-based, −1 none)."""
    x = -int(code) - 1
    return x // (_SURFACES * _SURFACES), x % _SURFACES - 1, (x // _SURFACES) % _SURFACES - 1


def signature_of(parent: np.ndarray, code: np.ndarray) -> np.ndarray:
    """(N,) int64 signatures of paths `parent` (N,) extended by event `code` (N,) (splitmix64)."""
    with np.errstate(over="ignore"):
        x = np.asarray(parent, np.int64).view(np.uint64) * _GOLDEN + (np.asarray(code, np.int64).astype(np.uint64)
                                                                      + _CODE_OFFSET)
        x = (x ^ (x >> np.uint64(30))) * _M1
        x = (x ^ (x >> np.uint64(27))) * _M2
        x = x ^ (x >> np.uint64(31))
    x = np.where(x == 0, np.uint64(1), x)  # 0 is the empty path
    return x.view(np.int64)


def binning(shape: tuple[int, int], max_side: int = PATH_IMAGE_MAX) -> int:
    """Pixel block so that a binned image has at most `max_side` pixels a side."""
    return max(1, math.ceil(max(shape) / max_side))


def binned_shape(shape: tuple[int, int], block: int) -> tuple[int, int]:
    return -(-shape[0] // block), -(-shape[1] // block)


def binned_pixel(pixel: np.ndarray, shape: tuple[int, int], block: int) -> np.ndarray:
    """Flat pixels (row-major (ny, nx)) → flat pixels of the binned image."""
    nx = shape[1]
    cnx = binned_shape(shape, block)[1]
    pixel = np.asarray(pixel, np.int64)
    return (pixel // nx) // block * cnx + (pixel % nx) // block


def _sparse_sum(key: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    keys, inverse = np.unique(key, return_inverse=True)
    return keys, np.bincount(inverse.reshape(-1), weights=value, minlength=len(keys))


@dataclass
class PassPaths:
    """One pass's detector light by path signature.

    signature : (K,) int64, sorted; flux : (K,) mm² (flux / E_sun) of each path
    events : signature → codes (every signature above, and their prefixes)
    image_signature, image_pixel, image_value : the sparse binned images, Σ irradiance (E/E_sun)
        over the detector pixels of each block (divide by the block's pixel count for the mean)
    shape : the detector's (ny, nx); block : the binning
    """

    signature: np.ndarray
    flux: np.ndarray
    events: dict[int, tuple[int, ...]]
    image_signature: np.ndarray
    image_pixel: np.ndarray
    image_value: np.ndarray
    shape: tuple[int, int]
    block: int


class PathTally:
    """Per-signature irradiance of one pass (see the module docstring).

    shape : detector (ny, nx); pixel_area_mm2 : one detector pixel's area
    """

    _COMPACT = 2_000_000  # stored sparse entries before they are summed again (bounds memory)

    def __init__(self, shape: tuple[int, int], pixel_area_mm2: float, max_side: int = PATH_IMAGE_MAX):
        self.shape = (int(shape[0]), int(shape[1]))
        self.pixel_area = float(pixel_area_mm2)
        self.block = binning(self.shape, max_side)
        self.n_binned = int(np.prod(binned_shape(self.shape, self.block)))
        self.events: dict[int, tuple[int, ...]] = {EMPTY: ()}
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._stored = 0

    def extend(self, parent: np.ndarray, code: np.ndarray) -> np.ndarray:
        """Signatures of `parent` (N,) extended by `code` (N,), recorded in `events`."""
        parent = np.asarray(parent, np.int64)
        code = np.asarray(code, np.int64)
        child = signature_of(parent, code)
        if len(child):
            new, first = np.unique(child, return_index=True)
            for s, i in zip(new.tolist(), first.tolist()):
                if s not in self.events:
                    self.events[s] = self.events[int(parent[i])] + (int(code[i]),)
        return child

    def add(self, signature: np.ndarray, pixel: np.ndarray, irradiance: np.ndarray) -> None:
        """Irradiance (N,) E/E_sun added to flat detector pixels (N,) by paths `signature` (N,)."""
        if not len(signature):
            return
        sigs, inverse = np.unique(np.asarray(signature, np.int64), return_inverse=True)
        key = inverse.reshape(-1).astype(np.int64) * self.n_binned + binned_pixel(pixel, self.shape, self.block)
        keys, sums = _sparse_sum(key, np.asarray(irradiance, np.float64))
        self._parts.append((sigs[keys // self.n_binned], keys % self.n_binned, sums))
        self._stored += len(keys)
        if self._stored > self._COMPACT:
            self._parts = [self._reduced()]
            self._stored = len(self._parts[0][0])

    def _reduced(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self._parts:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        sig, pix, val = (np.concatenate(a) for a in zip(*self._parts))
        sigs, inverse = np.unique(sig, return_inverse=True)
        keys, sums = _sparse_sum(inverse.reshape(-1).astype(np.int64) * self.n_binned + pix, val)
        return sigs[keys // self.n_binned], keys % self.n_binned, sums

    def finish(self) -> PassPaths:
        sig, pix, val = self._reduced()
        sigs, inverse = np.unique(sig, return_inverse=True)
        flux = np.bincount(inverse.reshape(-1), weights=val, minlength=len(sigs)) * self.pixel_area
        return PassPaths(sigs, flux, dict(self.events), sig, pix, val, self.shape, self.block)


@dataclass
class PassFaces:
    """One pass's light per CAD face (mesh tag).

    lit : (n_tags,) Σ flux of the photons arriving at each face, every bounce, mm² (flux / E_sun)
    seen : (n_tags,) Σ τ·A_pixel of the backward samples whose first face it is: the étendue with
        which the detector sees the face, mm²·sr; None when the pass traced no view map (forward)
    seen_tag, seen_pixel, seen_value : sparse binned images of τ (sr) per face (Σ over the pixels
        of each block), the detector's view of each face
    """

    lit: np.ndarray
    seen: np.ndarray | None = None
    seen_tag: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    seen_pixel: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    seen_value: np.ndarray = field(default_factory=lambda: np.zeros(0))


class FaceTally:
    """Per-face illuminated flux and detector étendue of one pass (`PassFaces`).

    left_out : (n_tags,) bool, faces kept at 0 (a mirror's coated face: the tracer ends a ray there
        only with probability p, weighted R·a/p, so its tallies would read a·R of its light; what
        it scatters is in the paths and its part's channel). None: every face is tallied."""

    def __init__(self, n_tags: int, shape: tuple[int, int], pixel_area_mm2: float, block: int,
                 left_out: np.ndarray | None = None):
        self.n_tags, self.shape, self.block = int(n_tags), shape, int(block)
        self.counted = np.ones(self.n_tags, bool) if left_out is None else ~np.asarray(left_out, bool)
        self.pixel_area = float(pixel_area_mm2)
        self.lit = np.zeros(self.n_tags)
        self.seen: np.ndarray | None = None
        self._images: tuple[np.ndarray, np.ndarray, np.ndarray] = (np.zeros(0, np.int64),) * 2 + (np.zeros(0),)

    def add_lit(self, tag: np.ndarray, flux: np.ndarray) -> None:
        tag = np.asarray(tag, np.int64)
        keep = self.counted[tag]
        self.lit += np.bincount(tag[keep], weights=np.asarray(flux)[keep], minlength=self.n_tags)[: self.n_tags]

    def add_seen(self, tag: np.ndarray, pixel: np.ndarray, tau: np.ndarray) -> None:
        """Backward samples (τ in sr) whose first face is `tag`, from flat detector pixels."""
        tag = np.asarray(tag, np.int64)
        keep = self.counted[tag]
        tag, pixel, tau = tag[keep], np.asarray(pixel)[keep], np.asarray(tau)[keep]
        seen = np.bincount(tag, weights=tau, minlength=self.n_tags)[: self.n_tags] * self.pixel_area
        self.seen = seen if self.seen is None else self.seen + seen
        n_binned = int(np.prod(binned_shape(self.shape, self.block)))
        keys, sums = _sparse_sum(tag * n_binned + binned_pixel(pixel, self.shape, self.block), tau)
        old_t, old_p, old_v = self._images
        keys, sums = _sparse_sum(np.concatenate([old_t * n_binned + old_p, keys]), np.concatenate([old_v, sums]))
        self._images = (keys // n_binned, keys % n_binned, sums)

    def copy(self) -> "FaceTally":
        """An independent tally holding what this one holds (`add_*` on either leaves the other as it is)."""
        other = copy.copy(self)
        other.lit = self.lit.copy()
        other.seen = None if self.seen is None else self.seen.copy()
        return other  # `_images` is a tuple of arrays that `add_seen` replaces, never writes into

    def finish(self) -> PassFaces:
        return PassFaces(self.lit.copy(), None if self.seen is None else self.seen.copy(), *self._images)


__all__ = ["EMPTY", "PATH_IMAGE_MAX", "ghost_code", "ghost_of", "signature_of", "binning", "binned_shape", "binned_pixel",
           "PassPaths", "PathTally", "PassFaces", "FaceTally"]
