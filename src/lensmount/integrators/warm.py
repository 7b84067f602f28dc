"""Compile the integrators' numba kernels (the gather area's nearest-boundary search and caps,
`radius._nearest_boundaries` and `_disc_areas`, the grid's k nearest, `neighbours._k_nearest`, which
r_0 and the boundary candidates share, and the gather's pair test and ladder sums,
`photon_gather._pairs_in_reach` and `_add_ladder`) into their cache once:
`python -m lensmount.integrators.warm`
(`make install` runs it after `lensmount.trace.warm`).

Why: cold, it takes 2-7 s to compile on the 2-core machine, which the first `simulate` (each of
its workers that starts before the cache is written) would pay in its first view map. The call
below goes through `FaceBoundaries.inside_areas`, so the kernels get a real run's argument types.
"""

from __future__ import annotations

import time

import numpy as np

from lensmount.integrators.photon_gather import Gatherer, HitPoints, PhotonHits
from lensmount.integrators.radius import FaceBoundaries


def main() -> None:
    start = time.perf_counter()
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    fb = FaceBoundaries(square, np.array([[0, 1, 2], [0, 2, 3]]), np.zeros(2, np.int64), 1)
    centre = np.array([[0.5, 0.5, 0.0]])
    fb.inside_areas(centre, np.array([[0.0, 0.0, 1.0]]), np.zeros(1, np.int32), (np.full(1, 0.2),), detector_z=1.0)
    # One photon gathered at one hit point, with the array types of a pass (the view map's, the walk's events).
    z = np.zeros((1, 3))
    up = np.array([[0.0, 0.0, 1.0]])
    hits = HitPoints(z, up, up, np.ones(1), np.zeros(1, np.int64), np.zeros(1, np.int32), np.zeros(1, np.int32),
                     np.ones(1))
    lambert = type("Lambert", (), {"eval": lambda self, wi, wo, n: np.full(len(wi), 0.1)})()
    Gatherer(hits, [lambert]).gather(PhotonHits(z, -up, up, np.ones(1), np.zeros(1, np.int32), np.zeros(1, np.int32)))
    print(f"lensmount: integrator kernels compiled and cached ({time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
