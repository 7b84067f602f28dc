"""Review findings, pinned: scatter seen from inside glass, and the scatter switch."""

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
from lens_scenes import glass_rim, singlet_barrel  # noqa: E402
from lensmount.integrators.bidirectional import bidirectional_pass  # noqa: E402
from lensmount.integrators.forward import forward_pass  # noqa: E402
from lensmount.scene.scene import Effects  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


def _mean_se(values):
    v = np.asarray(values)
    return v.mean(), v.std(ddof=1) / math.sqrt(len(v))


@pytest.mark.slow
def test_lens_rim_scattering_inside_the_glass_agrees_with_forward():
    """Without the 1/n² of radiance leaving glass, bidirectional read n² = 2.3 times forward."""
    scene = glass_rim()
    tracer = Tracer(scene)
    fw = _mean_se([forward_pass(scene, tracer, 400_000, 2, i).flux for i in range(6)])
    bi = _mean_se([bidirectional_pass(scene, tracer, 400_000, 1, i, 1.0, samples_per_pixel=64).flux for i in range(6)])
    assert abs(bi[0] - fw[0]) <= 3 * math.hypot(bi[1], fw[1]), (bi, fw)


def test_scatter_off_means_every_face_absorbs_in_both_estimators():
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.1), off_axis_deg=8.0, direct=True)
    on = bidirectional_pass(scene, Tracer(scene), 50_000, 1, 0, 1.0, samples_per_pixel=4)
    assert on.flux > 0  # the barrel does scatter when the switch is on
    off = replace(scene, effects=Effects(False, False, True))
    tracer = Tracer(off)
    for estimate in (forward_pass(off, tracer, 50_000, 1, 0),
                     bidirectional_pass(off, tracer, 50_000, 1, 0, 1.0, samples_per_pixel=4)):
        # No face scatters: no part can be a last scattering vertex, so no part has a channel.
        assert estimate.part_names == ["direct"]
