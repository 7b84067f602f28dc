"""Runner: bit-identical for any number of workers, stopping rules, checkpoint + resume."""

import math
import sys
from pathlib import Path

import numpy as np

# The planar world is the module `planar` (its tracer is named "planar:PlanarTracer" to the workers), as in
# planar_run.py.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
from planar import Collimated, Detector, Face, Lambert, PlanarScene  # noqa: E402

from lensmount.analysis.passes import Accumulator  # noqa: E402
from lensmount.integrators.estimate import film_channels  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.run.runner import PassJob, Runner, Stopping  # noqa: E402

TRACER = "planar:PlanarTracer"


def _scene():
    th = math.radians(30)
    d = (math.sin(th), 0, -math.cos(th))
    return PlanarScene([Face((0, 0, 0), (0, 0, 1), (1, 0, 0), (20.0, 0), "plate", disc=True)], [Lambert(0.2)],
                       Detector(2.0, 2.0, 4, 4, 20.0), Collimated(d, (-300 * d[0], 0, 300 * -d[2]), 25.0))


def _runner(scene, workers=1, checkpoint=None, acc=None):
    def job(i):
        return PassJob("bidirectional", 2000, 5, i, EstimatorSettings(samples_per_pixel=16))

    acc = acc or Accumulator.empty((4, 4), film_channels(scene), 0.25)
    return Runner(scene, job, acc, workers=workers, checkpoint=checkpoint, checkpoint_every=2,
                  checkpoint_meta={"seed": 5}, tracer_path=TRACER)


def test_same_result_with_one_or_two_workers():
    scene = _scene()
    a = _runner(scene, 1).run(Stopping(max_passes=6))
    b = _runner(scene, 2).run(Stopping(max_passes=6))
    assert a.n == b.n == 6
    np.testing.assert_array_equal(a.sum_image, b.sum_image)
    assert a.pass_flux == b.pass_flux


def test_resume_equals_one_long_run(tmp_path):
    scene = _scene()
    ck = tmp_path / "checkpoint.npz"
    _runner(scene, 1, checkpoint=ck).run(Stopping(max_passes=4))
    acc, meta = Accumulator.load(ck)
    assert acc.n == 4 and meta["seed"] == 5
    resumed = _runner(scene, 1, acc=acc).run(Stopping(max_passes=8))
    straight = _runner(scene, 1).run(Stopping(max_passes=8))
    np.testing.assert_array_equal(resumed.sum_image, straight.sum_image)
    assert resumed.last_pass == 7


def test_stopping_rules():
    scene = _scene()
    acc = _runner(scene).run(Stopping(photons=5000))
    assert acc.n == 3 and acc.photons == 6000
    acc = _runner(scene).run(Stopping(target_rel_error=0.5, min_passes=3))
    assert acc.n >= 3 and acc.rel_error() <= 0.5
    acc = _runner(scene).run(Stopping(time_s=0.0))
    assert acc.n == 1


def test_ctrl_c_keeps_the_passes_done(tmp_path):
    scene = _scene()
    ck = tmp_path / "ck.npz"

    def interrupt(acc, elapsed):
        if acc.n == 3:
            raise KeyboardInterrupt

    r = _runner(scene, 1, checkpoint=ck)
    r.progress = interrupt
    acc = r.run(Stopping(max_passes=100))
    assert r.interrupted and acc.n == 3
    assert Accumulator.load(ck)[0].n == 3
