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

from lensmount.integrators.photon_mapping.photon_gather import Gatherer, HitPoints, PhotonHits
from lensmount.integrators.photon_mapping.radius import FaceBoundaries, initial_radii


def main() -> None:
    start = time.perf_counter()
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    fb = FaceBoundaries(square, np.array([[0, 1, 2], [0, 2, 3]]), np.zeros(2, np.int64), 1)
    centre = np.array([[0.5, 0.5, 0.0]])
    fb.inside_areas(centre, np.array([[0.0, 0.0, 1.0]]), np.zeros(1, np.int32), (np.full(1, 0.2),), detector_z=1.0)
    # r_0 on a face with as many hit points as a pass puts there (the grid's k nearest, not the few-point path).
    rng = np.random.default_rng(0)
    plate = np.column_stack([rng.random((4096, 2)), np.zeros(4096)])
    radii = initial_radii(plate, np.zeros(4096, np.int32), np.full(1, 5.0))
    # Photons gathered at hit points, with the array types of a pass (the view map's, the walk's events; more
    # than one pair, so that the pair search hands over strided columns as it does in a run).
    n = 64
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    hits = HitPoints(plate[:n], up, up, np.ones(n), np.zeros(n, np.int64), np.zeros(n, np.int32),
                     np.zeros(n, np.int32), radii[:n])
    lambert = type("Lambert", (), {"eval": lambda self, wi, wo, n: np.full(len(wi), 0.1)})()
    for photons in (slice(0, n), slice(0, 1)):  # many pairs (strided columns), and a single one (contiguous)
        k = len(up[photons])
        gatherer = Gatherer(hits.subset(photons), [lambert])
        gatherer.gather(PhotonHits(plate[photons], -up[photons], up[photons], np.ones(k), np.zeros(k, np.int32),
                                   np.zeros(k, np.int32)))
    print(f"lensmount: integrator kernels compiled and cached ({time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
