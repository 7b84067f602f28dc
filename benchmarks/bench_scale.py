"""Scaling over workers: the same passes of case 2 on the reference design on 1, 2, 4 local
worker processes and on a 2-process Dask LocalCluster, in one run.

Printed: wall time for the passes (setup excluded: the pool and the cluster are started
and given one warm-up pass first), passes per second, and the ratio to one worker. The
accumulated flux series is compared too: every executor must give identical numbers.

`python benchmarks/bench_scale.py [passes]` (default 16 passes of 100 000 photons, 150 × 150 px).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "examples" / "double-gauss-360"
PHOTONS = 100_000


def _scene():
    """Case 2 at 150 × 150 px, through the loop's own first half (validated inputs, cached geometry)."""
    from lensmount.loop.prepare import build, read_inputs

    design, spec = read_inputs(DESIGN, DESIGN / "scenes" / "case2-lambertian.toml")
    spec = spec.model_copy(update={"detector": spec.detector.model_copy(update={"pixels": (150, 150)})})
    return build(design, spec, Path(tempfile.gettempdir()) / "lensmount-bench-geometry").scene


def _timed(scene, executor, passes: int):
    """Seconds for `passes` passes after one warm-up pass (tracer built, pool up), and the flux series."""
    from lensmount.analysis.passes import Accumulator
    from lensmount.integrators.bidirectional import part_names
    from lensmount.run.runner import PassJob, Runner, Stopping

    def job(i):
        return PassJob("bidirectional", PHOTONS, 1, i)

    acc = Accumulator.empty((scene.detector.ny, scene.detector.nx), part_names(scene), scene.detector.pixel_area)
    marks = []
    runner = Runner(scene, job, acc, executor=executor, progress=lambda a, e: marks.append(time.perf_counter()))
    runner.run(Stopping(max_passes=passes + executor.workers))
    # Time from the end of the first `workers` passes (warm-up: every worker has built its tracer) to the end.
    return marks[-1] - marks[executor.workers - 1], acc.pass_flux


def main() -> None:
    from lensmount.run.executor import executor_for

    passes = int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 16
    scene = _scene()
    print(f"case 2, reference design, 150 × 150 px, {PHOTONS:,} photons per pass, {passes} timed passes; "
          f"{os.cpu_count()} cores")
    base = reference = None
    for label, options in (("1 local worker", dict(workers=1)), ("2 local workers", dict(workers=2)),
                           ("4 local workers", dict(workers=4)), ("Dask LocalCluster, 2", dict(cluster="local:2"))):
        seconds, flux = _timed(scene, executor_for(**options), passes)
        rate = passes / seconds
        base = base or rate
        reference = reference or flux
        same = "identical" if flux[:passes] == reference[:passes] else "DIFFERENT NUMBERS"
        print(f"  {label:22s}: {seconds:7.1f} s, {rate:6.2f} passes/s, ×{rate / base:.2f} vs 1 worker ({same})")


if __name__ == "__main__":
    main()
