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
3. The phases of a pass (`phases`): case 1 and case 2 as `simulate` traces them (the plan's scene,
   the scene's photons per pass), one warm-up pass then `PHASE_PASSES` passes on one core: CPU
   seconds of the view map, the photon walk and the gather, and the view map's CPU per backward
   segment (`Tracer.segments`) against the forward walk's per segment measured in the same process:
   a bundle of FORWARD_BUNDLE photons of the scene's source through the same tracer (`Tracer.next_event`,
   one batch: the issue's "forward walk per segment"), and the pass's own photon walk (its BSDF sampling,
   film and roulette included; case 1's 2·10⁴ photons a pass make small batches). Ratios within one
   process hold on a loaded machine; the seconds are CPU.

`python benchmarks/bench_bidirectional.py [budget_seconds]` (default 60 s per method);
`python benchmarks/bench_bidirectional.py phases` for 3 alone.
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


PHASE_PASSES = 2
FORWARD_BUNDLE = 200_000
VIEW_MAP_CPU = "time/scatter: view map (hit points), CPU"
GATHER_CPU = "time/scatter: gather at hit points, CPU"
WALK_CPU = "time/photon walk (scatter, direct and ghosts together), CPU"


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
    from lensmount.integrators.photon_mapping.photon_gather import Gatherer, HitPoints, PhotonHits

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


def bench_phases(case: str) -> dict:
    """One case's phases (item 3 of the module docstring): per measured pass the CPU seconds by phase and
    the segments of the view map and of the photon walk; printed, and returned summed."""
    from lensmount.integrators import bidirectional as bidir
    from lensmount.integrators.plan import plan
    from lensmount.integrators.settings import EstimatorSettings
    from lensmount.integrators.walk import emit_photons
    from lensmount.loop.prepare import build, read_inputs
    from lensmount.physics.sampler import Streams
    from lensmount.trace.tracer import Tracer

    design, spec = read_inputs(DESIGN, DESIGN / "scenes" / f"{case}.toml")
    settings = EstimatorSettings()
    scene = plan(build(design, spec, Path(tempfile.gettempdir()) / "lensmount-bench-geometry").scene,
                 settings).scene
    tracer = Tracer(scene)
    integrator = bidir.Bidirectional(settings)
    seg = {"view map": 0}
    build_view_map = bidir.build_view_map

    def counted(*args, **kwargs):  # the view map's segments; the rest of a pass's are the photons'
        start = tracer.segments
        out = build_view_map(*args, **kwargs)
        seg["view map"] += tracer.segments - start
        return out

    bidir.build_view_map = counted
    try:
        integrator.run_pass(scene, tracer, 0, spec.run.photons, spec.run.seed)  # pilots, compiled code
        bundle = emit_photons(scene, 1, "bench", 0, FORWARD_BUNDLE, FORWARD_BUNDLE)
        tracer.segments, c0 = 0, time.process_time()
        tracer.next_event(bundle, Streams(1, "bench", bundle.id))
        forward = (time.process_time() - c0) / tracer.segments
        print(f"  {case}: forward bundle ({FORWARD_BUNDLE:,} photons of the source, one batch) "
              f"{1e9 * forward:.0f} ns per segment ({tracer.segments:,})")
        total = dict(view_map=0.0, walk=0.0, gather=0.0, view_segments=0, walk_segments=0)
        for i in range(1, 1 + PHASE_PASSES):
            seg["view map"], tracer.segments = 0, 0
            d = integrator.run_pass(scene, tracer, i, spec.run.photons, spec.run.seed).diagnostics
            vm, wk, ga = d[VIEW_MAP_CPU], d[WALK_CPU], d[GATHER_CPU]
            vs, ws = seg["view map"], tracer.segments - seg["view map"]
            print(f"  {case} pass {i}: CPU view map {vm:.2f} s, photon walk {wk:.2f} s, gather {ga:.2f} s; "
                  f"view map {1e9 * vm / vs:.0f} ns per backward segment ({vs:,}) = {vm / vs / forward:.2f}x the "
                  f"forward bundle's; photon walk {1e9 * wk / ws:.0f} ns per segment ({ws:,})")
            for k, v in (("view_map", vm), ("walk", wk), ("gather", ga), ("view_segments", vs),
                         ("walk_segments", ws)):
                total[k] += v
    finally:
        bidir.build_view_map = build_view_map
    per_backward = total["view_map"] / total["view_segments"]
    print(f"  {case}, {PHASE_PASSES} passes: CPU view map {total['view_map']:.2f} s, photon walk {total['walk']:.2f} s,"
          f" gather {total['gather']:.2f} s; view map per backward segment = {per_backward / forward:.2f}x the forward"
          f" bundle's (target 2x), {per_backward / (total['walk'] / total['walk_segments']):.2f}x the photon walk's")
    return total


def phases() -> None:
    print(f"phases of a pass, one core, CPU ({PHASE_PASSES} passes after a warm-up)")
    for case in ("case1-diaphragm-edge", "case2-lambertian"):
        bench_phases(case)


def main() -> None:
    if sys.argv[1:2] == ["phases"]:
        phases()
        return
    budget = float(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].replace(".", "").isdigit() else 60.0
    bench_gather()
    bench_case1(budget)
    phases()


if __name__ == "__main__":
    main()
