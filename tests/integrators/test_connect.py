"""Light on faces the detector sees straight (`integrators.photon_mapping.connect`): which hit points give way to the
photons' connections, and that both ways of counting that light read the same."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.integrators.bidirectional import Bidirectional  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.physics.rays import RayBatch  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


@pytest.fixture(scope="module")
def barrel():
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.05), off_axis_deg=8.0, pixels=(16, 16))
    return scene, Tracer(scene)


def test_the_view_map_leaves_out_the_hit_points_that_see_the_detector_straight(barrel):
    """Checked by the geometry, not by the backward ray's bits: from a hit point along ω_o, the first
    thing met is the detector's front, in the hit point's own pixel, exactly for the points the view map
    leaves out when the photons are connected (the barrel behind the singlet); the points it keeps look
    back into the glass, and are the same points, bit for bit, as without connections."""
    scene, tracer = barrel
    every = Bidirectional(EstimatorSettings(connect_direct_view=False)).view_pass(scene, tracer, 0, 3).hits
    kept = Bidirectional().view_pass(scene, tracer, 0, 3).hits
    seen = tracer.intersect(RayBatch.make(every.position, every.omega_o), origin_normal=every.normal)
    straight = seen.detector & seen.detector_front & (scene.detector.pixel_of(seen.point) == every.pixel)
    rows = {tuple(p) for p in np.column_stack([kept.position, kept.pixel])}
    in_kept = np.array([tuple(p) in rows for p in np.column_stack([every.position, every.pixel])])
    assert in_kept.sum() == len(kept) and (~in_kept).sum() > 100 and in_kept.sum() > 10
    assert np.mean(in_kept == ~straight) > 0.999, ((~in_kept).sum(), straight.sum())
    on_both = np.flatnonzero(in_kept)
    assert np.array_equal(every.weight[on_both], kept.weight)


def test_connections_and_the_gather_read_the_same_barrel(barrel):
    """The barrel inside a singlet's mount, lit through the lens at 8°: the light of the barrel behind the
    lens counted by connections, or by the gather, agrees within the combined error (the light the
    detector sees through the glass is the gather's either way)."""
    scene, tracer = barrel
    reads = {}
    for connect in (False, True):
        run = Bidirectional(EstimatorSettings(connect_direct_view=connect))
        flux = np.array([run.run_pass(scene, tracer, i, 20_000, 5).flux for i in range(6)])
        reads[connect] = flux.mean(), flux.std(ddof=1) / math.sqrt(len(flux))
    (a, sa), (b, sb) = reads[False], reads[True]
    assert a > 0 and abs(a - b) < 3 * math.hypot(sa, sb), reads
    assert sb < sa, reads  # and the connections are the less noisy way
