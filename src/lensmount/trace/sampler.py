"""Random streams keyed by (seed, stream, index): the same numbers on one core or a cluster.

Every pass of every integrator draws from `stream(seed, purpose, pass_index)`, so a
pass's result depends only on its key, never on which worker ran it or in what order.
"""

from __future__ import annotations

import zlib

import numpy as np


def stream(seed: int, purpose: str, index: int = 0) -> np.random.Generator:
    """An independent generator for (run seed, purpose, index); `purpose` names the use ("photons", "view-map")."""
    if int(seed) < 0 or int(index) < 0:
        raise ValueError(f"seed and index must be >= 0, got seed={seed}, index={index}")
    key = [int(seed), zlib.crc32(purpose.encode()), int(index)]
    return np.random.Generator(np.random.Philox(np.random.SeedSequence(key)))
