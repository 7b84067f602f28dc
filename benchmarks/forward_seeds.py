"""Forward seeds on a scene at one off-axis angle: do the error bars quoted match the spread between seeds?

    python benchmarks/forward_seeds.py DESIGN SCENE ANGLE SEEDS PASSES PHOTONS
    e.g. python benchmarks/forward_seeds.py examples/cooke-triplet examples/cooke-triplet/scenes/case2-lambertian.toml 35 12 16 250000

Each seed is a run of PASSES forward passes (`forward_pass`, its totals into an `Accumulator`), read with the
tail rule shipped (the bound the forward pass states on a term) and with the rule before on the same passes
(no bound stated: Grubbs's test and the tail index). Prints each seed as a JSON line, then the spread of the
seeds against the mean error they quote and how many seeds' ±2σ hold the other seeds' mean.
"""

import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from lensmount.analysis.passes import Accumulator
from lensmount.integrators.forward import forward_pass
from lensmount.loop.prepare import build, read_inputs
from lensmount.scene.build import make_source
from lensmount.trace.tracer import Tracer


def main(design: str, scene_file: str, angle: float, seeds: int, passes: int, photons: int) -> None:
    d, spec = read_inputs(Path(design), Path(scene_file))
    scene = build(d, spec).scene
    source = make_source(spec.source.model_copy(update={"off_axis_deg": angle}), scene.front_opening, scene.mesh,
                         scene.detector, d.prescription)
    scene = dataclasses.replace(scene, source=source)
    tracer = Tracer(scene)
    rows, start = [], time.time()
    for seed in range(1, seeds + 1):
        acc = None
        for i in range(passes):
            e = forward_pass(scene, tracer, photons, seed, i).totals()
            acc = acc or Accumulator.empty((1, 1), e.part_names, e.pixel_area_mm2)
            acc.add(e, i)
        t = acc.tail()
        now = dict(flux=acc.flux, se=acc.flux_std_error, heavy=bool(t.heavy), p=t.p, allowance=t.allowance)
        acc.pass_term_bound = [math.inf] * acc.n  # the rule before: no bound stated
        t = acc.tail()
        rows.append(dict(seed=seed, now=now, before=dict(se=acc.flux_std_error, heavy=bool(t.heavy), p=t.p,
                                                          index=t.index)))
        print(json.dumps(rows[-1]), f"{time.time() - start:.0f} s", flush=True)
    flux = np.array([r["now"]["flux"] for r in rows])
    se = np.array([r["now"]["se"] for r in rows])
    spread = float(np.std(flux, ddof=1))
    print(f"{angle:g}°: {seeds} seeds × {passes} passes × {photons}: mean {flux.mean():.5g}, seeds spread "
          f"{spread / flux.mean():.4f}, quote {se.mean() / flux.mean():.4f} on average (ratio {spread / se.mean():.2f}); "
          f"before: {sum(not math.isfinite(r['before']['se']) for r in rows)} without error bar, "
          f"{sum(r['before']['heavy'] for r in rows)} dominated by a pass; now: "
          f"{sum(not math.isfinite(s) for s in se)} without, {sum(r['now']['heavy'] for r in rows)} dominated")
    held = sum(abs(flux[k] - np.delete(flux, k).mean()) <= 2 * se[k] for k in range(seeds))
    print(f"±2σ holds the other seeds' mean in {held} of {seeds}")


if __name__ == "__main__":
    a = sys.argv[1:]
    main(a[0], a[1], float(a[2]), int(a[3]), int(a[4]), int(a[5]))
