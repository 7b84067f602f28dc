"""Per-pass flux of the singlet-in-a-barrel scene past its field: forward, bidirectional without and with the
connection through the optics (mean, standard error, spread, seconds a pass). Usage:
python benchmarks/through_optics/through_optics_check.py ANGLE PASSES PHOTONS_BIDIR PHOTONS_FORWARD"""

import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "integrators"))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.integrators.bidirectional import Bidirectional  # noqa: E402
from lensmount.integrators.forward import Forward  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402

angle, passes, n_b, n_f = float(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.5), off_axis_deg=angle, pixels=(8, 8))
tracer = Tracer(scene)
methods = {"bidir-off": Bidirectional(dataclasses.replace(EstimatorSettings(), connect_through_optics=False)),
           "bidir-on": Bidirectional(dataclasses.replace(EstimatorSettings(), connect_through_optics=True)), "forward": Forward()}
for name, m in methods.items():
    n = n_f if name == "forward" else n_b
    t0 = time.perf_counter()
    x = np.array([m.run_pass(scene, tracer, i, n, 9).flux for i in range(passes)])
    dt = (time.perf_counter() - t0) / passes
    print(f"{name:10s} mean {x.mean():.5e} ± {x.std(ddof=1) / math.sqrt(passes):.2e} "
          f"({100 * x.std(ddof=1) / math.sqrt(passes) / x.mean():.1f} %), pass spread {100 * x.std(ddof=1) / x.mean():.0f} %, "
          f"max/median {x.max() / np.median(x):.2f}, {dt:.2f} s/pass", flush=True)
