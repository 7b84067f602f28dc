"""Optics foundation speed: real-ray trace throughput, ray aiming, automatic clear
apertures and the beam envelope, on the reference double Gauss (11 surfaces)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lensmount.design.lens import load_lens
from lensmount.optics.apertures import beam_envelope, with_clear_semi_diameters
from lensmount.optics.realrays import aim, field_direction, trace

LENS = Path(__file__).resolve().parents[1] / "examples" / "double-gauss-360" / "lens.toml"


def _best(fn, repeat=3):
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def main() -> None:
    t = time.perf_counter()
    lens = load_lens(LENS)
    print(f"load_lens (incl. glass catalogues, auto apertures): {time.perf_counter() - t:.2f} s")
    raw = load_lens(LENS, auto_clear_apertures=False)

    n = 1_000_000
    rng = np.random.default_rng(0)
    o = np.column_stack([rng.uniform(-20, 20, n), rng.uniform(-20, 20, n), np.zeros(n)])
    d = np.repeat(field_direction([2.0]), n, axis=0)
    dt = _best(lambda: trace(lens, o, d), repeat=2)
    print(f"trace: {n:,} rays x {len(lens.surfaces)} surfaces in {dt:.2f} s "
          f"= {n * len(lens.surfaces) / dt / 1e6:.1f} M ray-surfaces/s")

    pupil = np.column_stack([rng.uniform(-0.7, 0.7, 10_000), rng.uniform(-0.7, 0.7, 10_000)])
    dt = _best(lambda: aim(lens, [0.0, 3.5, 5.0], pupil))
    print(f"aim (real rays at the stop): 30,000 rays in {dt * 1e3:.0f} ms")

    dt = _best(lambda: with_clear_semi_diameters(raw))
    print(f"with_clear_semi_diameters: {dt * 1e3:.0f} ms")

    z = np.linspace(-100.0, 520.0, 1000)
    dt = _best(lambda: beam_envelope(lens, z))
    print(f"beam_envelope at 1000 z: {dt * 1e3:.0f} ms")


if __name__ == "__main__":
    main()
