"""The kernel-bias bound from the ladder of radii on a real case, one run per seed (CHANGELOG.md,
"The view map", "After: the ladder of radii").

    python benchmarks/bias_ladder.py run DESIGN SCENE PHOTONS PASSES FIRST_SEED SEEDS OUT.npz
    python benchmarks/bias_ladder.py table OUT.npz[,MORE.npz] [PASSES]

`run` saves every pass's per-part flux and its flux on the ladder (`PassEstimate.part_flux_ladder`) after
each pass (interrupt it any time); `table` gives, per seed, the stray flux, its standard error, the
ladder's bound (`analysis.bias.ladder_bias`) and the old half-radius bound |2 D̄| + se(2 D) from the same
passes, and whether 2 se + bound holds the pooled mean of all passes.
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def run(design, scene_file, photons, passes, first_seed, seeds, out) -> None:
    from lensmount.integrators.bidirectional import Bidirectional
    from lensmount.loop.prepare import build, read_inputs
    from lensmount.trace.tracer import Tracer

    d, spec = read_inputs(Path(design), Path(scene_file))
    scene = build(d, spec, Path(tempfile.gettempdir()) / "lensmount-bias-geometry").scene
    tracer, method = Tracer(scene), Bidirectional()
    flux, ladder, seed_of = [], [], []
    for seed in range(int(first_seed), int(first_seed) + int(seeds)):
        for i in range(int(passes)):
            start = time.perf_counter()
            e = method.run_pass(scene, tracer, i, int(photons), seed)
            flux.append(e.part_flux), ladder.append(e.part_flux_ladder), seed_of.append(seed)
            print(f"seed {seed} pass {i}: {time.perf_counter() - start:.1f} s, flux {e.flux:.6g} mm²", flush=True)
            np.savez(out, flux=np.array(flux), ladder=np.array(ladder), seed=np.array(seed_of))


def table(files: str, passes: int = 8) -> None:
    from lensmount.analysis.bias import ladder_bias
    from lensmount.analysis.error_bar import t_factor
    from lensmount.integrators.photon_mapping.photon_gather import BIAS_LADDER

    half = BIAS_LADDER.index(0.5)
    data = [np.load(f) for f in files.split(",")]
    flux = np.concatenate([z["flux"].sum(axis=1) for z in data])
    ladder = np.concatenate([z["ladder"].sum(axis=2) for z in data])
    seed = np.concatenate([z["seed"] for z in data])
    pooled = flux.mean()
    print(f"pooled: {len(flux)} passes, {pooled:.6g} mm² ± {100 * flux.std(ddof=1) / math.sqrt(len(flux)) / pooled:.2f} %")
    print("| seed | flux (mm²) | standard error | bias bound (ladder) | old bound | 2 se + bound holds the pooled mean |")
    print("|---|---:|---:|---:|---:|---|")
    for s in np.unique(seed):
        f, rungs = flux[seed == s][:passes], ladder[seed == s][:passes]
        if len(f) < passes:
            continue
        widen = t_factor(passes) / math.sqrt(passes)
        se = np.std(f, ddof=1) * widen
        bias = ladder_bias(f, rungs, t_factor)
        d = 2 * (f - rungs[:, half])
        old = abs(d.mean()) + np.std(d, ddof=1) * widen
        bound = f"{100 * bias.bound / f.mean():.2f} %" if bias.bounded else f"none: {bias.reason}"
        holds = abs(f.mean() - pooled) <= 2 * se + bias.bound if bias.bounded else "(no bound)"
        print(f"| {s} | {f.mean():.6g} | {100 * se / f.mean():.2f} % | {bound} | {100 * old / f.mean():.2f} % | {holds} |")


if __name__ == "__main__":
    if len(sys.argv) >= 9 and sys.argv[1] == "run":
        run(*sys.argv[2:9])
    elif len(sys.argv) >= 3 and sys.argv[1] == "table":
        table(sys.argv[2], *(int(a) for a in sys.argv[3:4]))
    else:
        sys.exit(__doc__)
