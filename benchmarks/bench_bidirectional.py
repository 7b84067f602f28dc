"""Bidirectional vs forward on the seed paper's case 1, and the neighbour search's scaling.

Figures printed:
1. Case 1 (50 µm diaphragm edge, Lambertian 10 %), reference design, 600 × 600 pixels:
   wall time for each method to reach 5 % relative error on the total stray flux (standard
   error and bias bound together, as `simulate --target-rel-error` stops), and their ratio.
   Each method runs passes for a time budget; if it has not reached 5 % its time is
   extrapolated from its measured error (rel. error ∝ 1/√time, passes being independent).
   Both on one core, same machine, same run.
2. Photon gather: time to gather M photons into H hit points (cKDTree pairs), showing
   near-linear scaling in M.

`python benchmarks/bench_bidirectional.py [budget_seconds]` (default 60 s per method).
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "examples" / "double-gauss-360"
TARGET = 0.05


def _case1_scene():
    """Case 1 as `lensmount simulate` builds it: loop.prepare's read_inputs + build (the scene file's
    checks included), geometry cached in the temp folder the other benchmarks share."""
    from lensmount.loop.prepare import build, read_inputs

    design, spec = read_inputs(DESIGN, DESIGN / "scenes" / "case1-diaphragm-edge.toml")
    return build(design, spec, Path(tempfile.gettempdir()) / "lensmount-bench-geometry").scene


def _time_to_target(run_pass, budget_s: float, min_passes: int = 8):
    """Run passes until 5 % or the budget: (time to 5 % (measured or extrapolated), passes, rel, measured?,
    seconds run, Accumulator).

    The relative error is the one `simulate --target-rel-error` stops on (`Accumulator.rel_error`:
    the standard error widened by Student's t, plus the kernel-bias bound for bidirectional), checked
    from `min_passes` on as the runner does; time includes each method's first pass (its pilots)."""
    from lensmount.analysis.passes import Accumulator

    acc = None
    start = time.perf_counter()
    while True:
        estimate = run_pass(0 if acc is None else acc.n)
        if acc is None:
            acc = Accumulator.empty(estimate.image.shape, estimate.part_names, estimate.pixel_area_mm2)
        acc.add(estimate)
        elapsed = time.perf_counter() - start
        rel = acc.rel_error()
        if acc.n >= min_passes and rel <= TARGET:
            return elapsed, acc.n, rel, True, elapsed, acc
        if elapsed >= budget_s and (acc.n >= min_passes or (acc.n >= 3 and not math.isfinite(rel))):
            t = elapsed * (rel / TARGET) ** 2 if math.isfinite(rel) else math.inf
            return t, acc.n, rel, False, elapsed, acc


def bench_case1(budget_s: float) -> None:
    from lensmount.integrators.bidirectional import Bidirectional
    from lensmount.integrators.forward import forward_pass
    from lensmount.trace.tracer import Tracer

    t0 = time.perf_counter()
    scene = _case1_scene()
    tracer = Tracer(scene)
    print(f"case 1 scene: {len(scene.mesh.triangles)} triangles, {scene.detector.nx}×{scene.detector.ny} px "
          f"(setup {time.perf_counter() - t0:.1f} s)")
    bidirectional = Bidirectional()
    # Photons per pass: the scene's for bidirectional (20 000, most aimed at the edge), 10⁶ for forward.
    fw_photons = 1_000_000
    bi = _time_to_target(lambda i: bidirectional.run_pass(scene, tracer, i, 20_000, 1), budget_s)
    fw = _time_to_target(lambda i: forward_pass(scene, tracer, fw_photons, 1, i), budget_s)
    for name, (t, n, rel, measured, _, _) in (("bidirectional", bi), ("forward", fw)):
        how = "measured" if measured else f"extrapolated from {100 * rel:.1f} % after {n} passes"
        print(f"  {name:13s}: time to {100 * TARGET:.0f} % rel. error = {t:9.1f} s ({how}; {n} passes)")
    fw_time = fw[0]
    if not math.isfinite(fw_time) and math.isfinite(bi[0]):
        # No forward photon reached the detector: its time from counting statistics instead. A forward photon
        # reaches the detector only after one Lambertian scatter at the edge (ρ = 0.1), carrying ρ A_S / N, so
        # it counts with probability p = flux / (ρ A_S) and 5 % needs 1 / (p · 0.05²) photons.
        p = bi[5].flux / (0.10 * scene.source.disc.area)
        photons = 1.0 / (p * TARGET**2)
        rate = fw[1] * fw_photons / fw[4]
        fw_time = photons / rate
        print(f"  forward      : no photon of {fw[1] * fw_photons:,} reached the detector; at p = {p:.2g} per photon "
              f"(bidirectional's flux / (ρ A_S)) 5 % needs {photons:.2g} photons = {fw_time:.3g} s at its "
              f"measured {rate:,.0f} photons/s")
    if math.isfinite(bi[0]) and bi[0] > 0:
        ratio = fw_time / bi[0]
        print(f"  forward / bidirectional time ratio = {ratio:.1f}" if math.isfinite(ratio)
              else "  forward / bidirectional time ratio = inf (forward put no photon on the detector)")


def bench_gather() -> None:
    from lensmount.integrators.photon_gather import Gatherer, HitPoints, PhotonHits

    class Lambert:
        def eval(self, wi, wo, n):
            return np.full(len(wi), 0.1 / math.pi)

    rng = np.random.default_rng(0)
    h = 100_000
    pos = np.column_stack([rng.uniform(0, 100, (h, 2)), np.zeros(h)])
    nz = np.tile([0, 0, 1.0], (h, 1))
    hits = HitPoints(pos, nz, nz.copy(), np.ones(h), np.arange(h), np.zeros(h, np.int32), np.zeros(h, np.int32),
                     np.full(h, 0.3))
    t0 = time.perf_counter()
    g = Gatherer(hits, [Lambert()])
    print(f"gather: {h} hit points indexed in {time.perf_counter() - t0:.3f} s")
    for m in (10_000, 100_000, 1_000_000):
        p = np.column_stack([rng.uniform(0, 100, (m, 2)), np.zeros(m)])
        photons = PhotonHits(p, np.tile([0, 0, -1.0], (m, 1)), np.tile([0, 0, 1.0], (m, 1)), np.ones(m),
                             np.zeros(m, np.int32), np.zeros(m, np.int32))
        t0 = time.perf_counter()
        g.gather(photons)
        dt = time.perf_counter() - t0
        print(f"  {m:>9,} photons: {dt:7.3f} s  ({1e6 * dt / m:.2f} µs/photon, {g.pairs_tested:,} pairs so far)")


def main() -> None:
    budget = float(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].replace(".", "").isdigit() else 60.0
    bench_gather()
    bench_case1(budget)


if __name__ == "__main__":
    main()
