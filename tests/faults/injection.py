"""Faults to inject, chosen by a seeded generator so that a failing case names what to replay.

`damage(path, rng)` truncates a file, empties it or flips one bit in it; `cases(kind, n, seed)`
yields (seed, description) pairs for pytest ids. Every injected fault is recorded
(fault_log.record) so the session prints how many there were.
"""

from __future__ import annotations

import random
from pathlib import Path

from fault_log import record

HOW = ("truncate", "zero bytes", "bit flip")


def damage(path: Path, seed: int, how: str | None = None) -> str:
    """Damage `path` in place as the seed chooses (or as `how` says); the description, recorded."""
    rng = random.Random(seed)
    how = how or rng.choice(HOW)
    data = bytearray(path.read_bytes())
    if how == "zero bytes":
        data = bytearray()
        what = how
    elif how == "truncate":
        cut = rng.randrange(len(data))
        data = data[:cut]
        what = f"truncated to {cut} of {len(path.read_bytes())} bytes"
    else:
        i, bit = rng.randrange(len(data)), rng.randrange(8)
        data[i] ^= 1 << bit
        what = f"bit {bit} of byte {i} flipped"
    path.write_bytes(bytes(data))
    description = f"{path.name}: {what} (seed {seed})"
    record(description)
    return description


def seeds(kind: str, n: int, base: int = 0) -> list[int]:
    """n seeds for the faults of one kind: the same on every run, different per kind."""
    rng = random.Random(f"{kind}:{base}")
    return [rng.randrange(2**31) for _ in range(n)]
