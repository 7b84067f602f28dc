"""Per-pass PST-scene flux of a design at one angle, bidirectional without / with the connection through the
optics (and optionally forward): python benchmarks/through_optics/through_optics_ref.py DESIGN SCENE ANGLE PASSES PHOTONS SEED[,SEED…] [off,on,forward]
Prints one line per method: mean, standard error, pass spread, max/median, s a pass; and the passes."""

import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

from lensmount.integrators.bidirectional import Bidirectional
from lensmount.integrators.forward import Forward
from lensmount.integrators.settings import EstimatorSettings
from lensmount.loop.prepare import build, read_inputs
from lensmount.scene.build import make_source
from lensmount.trace.tracer import Tracer

design_dir, scene_file, angle, passes, photons = (Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3]),
                                                  int(sys.argv[4]), int(sys.argv[5]))
seeds = [int(x) for x in sys.argv[6].split(",")]
methods = sys.argv[7].split(",") if len(sys.argv) > 7 else ["off", "on"]
design, spec = read_inputs(design_dir, scene_file)
base = build(design, spec, None).scene
source = make_source(spec.source.model_copy(update={"off_axis_deg": angle}), base.front_opening, base.mesh,
                     base.detector, design.prescription)
scene = dataclasses.replace(base, source=source)
tracer = Tracer(scene)
settings = EstimatorSettings(view_map_pitch=spec.run.view_map_pitch)
make = {"off": lambda: Bidirectional(dataclasses.replace(settings, connect_through_optics=False)),
        "on": lambda: Bidirectional(dataclasses.replace(settings, connect_through_optics=True)), "forward": lambda: Forward(settings)}
for seed, name in ((s, n) for s in seeds for n in methods):
    m = make[name]()
    t0 = time.perf_counter()
    x = np.array([m.run_pass(scene, tracer, i, photons, seed).flux for i in range(passes)])
    dt = (time.perf_counter() - t0) / passes
    se = x.std(ddof=1) / math.sqrt(passes)
    print(f"{angle:4.0f}° seed {seed} {name:8s} mean {x.mean():.4e} ± {se:.2e} ({100 * se / x.mean():.1f} %) "
          f"spread {100 * x.std(ddof=1) / x.mean():.0f} % max/median {x.max() / np.median(x):.2f} {dt:.1f} s/pass "
          f"passes {' '.join(f'{v:.3e}' for v in x)}", flush=True)
