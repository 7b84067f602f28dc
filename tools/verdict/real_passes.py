"""Real pass values of case 2 on a small detector, many seeds: input to the coverage check (issue 26).

    PYTHONPATH=src nice -n 10 python tools/verdict/real_passes.py forward 2000 250 8
writes /tmp/verdict/passes-forward-2000.npy (seeds x passes); tests/loop/data holds that run's values.
"""
import shutil, sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repo root: the tests.loop helpers
from tests.loop.test_compare_slow import SMALL_CASE2
from tests.loop.runs import EXAMPLE
from lensmount.mesh import TaggedMesh
from lensmount.design.folder import load_design
from lensmount.design.scene import load_scene
from lensmount.loop.regenerate import RegenerateOptions, regenerate
from lensmount.run.runner import PassJob, run_pass
from lensmount.scene.build import build_scene
from lensmount.trace.tracer import Tracer

method, photons, seeds, passes = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
design = Path("/tmp/verdict/design")
design.parent.mkdir(parents=True, exist_ok=True)
if not design.exists():
    shutil.copytree(EXAMPLE, design, ignore=shutil.ignore_patterns("build", ".lensmount", "scenes"))
    (design / "scenes").mkdir()
    (design / "scenes" / "small2.toml").write_text(SMALL_CASE2)
built = regenerate(RegenerateOptions(design))
sc = build_scene(load_design(design).prescription, TaggedMesh.load(built.folder / built.manifest.mesh),
                 load_scene(design / "scenes" / "small2.toml"))
tracer = Tracer(sc)
out = Path(f"/tmp/verdict/passes-{method}-{photons}.npy")
vals = np.full((seeds, passes), np.nan)
t0 = time.time()
for s in range(seeds):
    for i in range(passes):
        vals[s, i] = run_pass(sc, tracer, PassJob(method, photons, 5000 + s, i)).flux
    if s % 10 == 9:
        np.save(out, vals[: s + 1]); print(s + 1, time.time() - t0, flush=True)
np.save(out, vals)
