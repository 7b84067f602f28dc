"""What one pass of a `pst` sweep costs: the view map once, then each angle's photons (CPU seconds).

Case 2 of the reference design (600 × 600 px, 10⁵ photons a pass), pass PASS (default 0), one
process: the tracer's build, `Bidirectional.view_pass` once, `photon_pass` (+ `totals`) per angle
with its walk and gather. Before the view map was shared, each angle paid view map + photons; now a
pass of A angles costs one view map + A × photons (CHANGELOG.md, "The loop", "pst with one view map").

    python benchmarks/bench_pst_pass.py [ANGLES=0,10,20,30] [PASS=0] [GEOMETRY=examples/double-gauss-360/build]

Mesh: `lensmount.cad.regenerate` of examples/double-gauss-360 into GEOMETRY (cached).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

from lensmount.integrators.bidirectional import Bidirectional
from lensmount.integrators.estimate import CPU_SUFFIX, PHASES, TIME_PREFIX
from lensmount.loop.prepare import build, read_inputs
from lensmount.scene.build import make_source
from lensmount.trace.tracer import Tracer

DESIGN = Path(__file__).resolve().parents[1] / "examples" / "double-gauss-360"


def main(angles: list[float], pass_index: int, geometry: Path | None, photons: int = 100_000, seed: int = 1) -> None:
    design, spec = read_inputs(DESIGN, DESIGN / "scenes" / "case2-lambertian.toml")
    base = build(design, spec, geometry).scene
    clock = time.process_time()
    tracer = Tracer(base)
    print(f"tracer: {time.process_time() - clock:.2f} CPU s")
    bidir = Bidirectional()
    clock = time.process_time()
    view = bidir.view_pass(base, tracer, pass_index, seed)
    view_s = time.process_time() - clock
    print(f"view map: {view_s:.2f} CPU s, {len(view.hits):,} hit points")
    total = 0.0
    for angle in angles:
        source = make_source(spec.source.model_copy(update={"off_axis_deg": angle}), base.front_opening, base.mesh,
                             base.detector, design.prescription)
        scene = dataclasses.replace(base, source=source)
        clock = time.process_time()
        estimate = bidir.photon_pass(scene, tracer, view, pass_index, photons, seed).totals()
        cpu = time.process_time() - clock
        total += cpu
        walk, gather = (estimate.diagnostics[TIME_PREFIX + PHASES[k] + CPU_SUFFIX] for k in ("walk", "gather"))
        print(f"{angle:5g}°: photons {cpu:.2f} CPU s (walk {walk:.2f}, gather {gather:.2f}), "
              f"flux {estimate.flux:.4e} mm²")
    n = len(angles)
    print(f"a pass of {n} angles: before {n * view_s + total:.1f} CPU s (a view map each), "
          f"now {view_s + total:.1f} CPU s")


if __name__ == "__main__":
    main([float(a) for a in (sys.argv[1] if len(sys.argv) > 1 else "0,10,20,30").split(",")],
         int(sys.argv[2]) if len(sys.argv) > 2 else 0, Path(sys.argv[3]) if len(sys.argv) > 3 else None)
