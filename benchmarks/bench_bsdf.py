"""BSDF throughput: million rays per second for eval, sample, pdf and albedo, per model.

Run: `python benchmarks/bench_bsdf.py` (or `python benchmarks/run.py bsdf`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from lensmount.physics.bsdf import make_bsdf
from lensmount.physics.sampler import stream

MODELS = [
    ("lambertian", {"reflectance": 0.1}),
    ("gaussian", {"reflectance": 0.05, "half_width_deg": 5.0}),
    ("gaussian", {"reflectance": 0.05, "half_width_deg": 0.05}),
    ("abg", {"A": 1e-3, "B": 1e-4, "g": 2.0}),
    ("harvey", {"b0": 10.0, "L": 0.01, "S": -1.5}),
    ("mirror", {"reflectance": 0.9}),
]


def _rate(call, count: int, repeat: int = 3) -> float:
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return count / best / 1e6


def main() -> None:
    count = 200_000
    rng = stream(0, "bench-bsdf")
    theta = np.arccos(rng.random(count))
    wi = np.stack([np.sin(theta), np.zeros(count), np.cos(theta)], axis=1)
    n = np.tile([0.0, 0.0, 1.0], (count, 1))
    u = rng.random((count, 2))
    print(f"{'model':<50} {'build s':>8} {'eval':>7} {'sample':>7} {'pdf':>7} {'albedo':>7}  (M rays/s, N = {count})")
    for model, params in MODELS:
        start = time.perf_counter()
        bsdf = make_bsdf(model, **params)
        bsdf.albedo(wi[:1], n[:1])  # builds the albedo table where there is one
        build = time.perf_counter() - start
        wo, _, _ = bsdf.sample(wi, n, u)
        rates = [_rate(lambda: bsdf.eval(wi, wo, n), count), _rate(lambda: bsdf.sample(wi, n, u), count),
                 _rate(lambda: bsdf.pdf(wi, wo, n), count), _rate(lambda: bsdf.albedo(wi, n), count)]
        print(f"{repr(bsdf):<50} {build:8.3f} " + " ".join(f"{r:7.2f}" for r in rates), flush=True)


if __name__ == "__main__":
    main()
