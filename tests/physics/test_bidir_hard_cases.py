"""Hard cases stay finite and their error bars cover the reference.

References: the forward estimator (the other engineer's code) on the singlet-in-a-barrel
scene; the analytic Lambertian disc on the planar scene; for the diaphragm edge, the
estimator's own scaling law (halving the edge's width halves its channel, which a leak
from the plate faces would not do).
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
from lens_scenes import double_gauss_case, singlet_barrel  # noqa: E402
from planar import Collimated, Detector, Face, PlanarScene, PlanarTracer  # noqa: E402

from lensmount.analysis.passes import Accumulator  # noqa: E402
from lensmount.analysis.summary import build_summary  # noqa: E402
from lensmount.integrators.bidirectional import bidirectional_pass  # noqa: E402
from lensmount.integrators.forward import forward_pass  # noqa: E402
from lensmount.integrators.radius import radius_scale  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.results import write_run  # noqa: E402
from lensmount.trace.bsdf import make_bsdf  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


def _stats(values):
    v = np.asarray(values, float)
    assert np.all(np.isfinite(v))
    return v.mean(), v.std(ddof=1) / math.sqrt(len(v))


def _bidir_vs_forward(scene, passes=6, photons=50_000, spp=16):
    tracer = Tracer(scene)
    est = [bidirectional_pass(scene, tracer, photons, 3, i, 1.0, samples_per_pixel=spp) for i in range(passes)]
    for e in est:
        assert np.all(np.isfinite(e.image)) and np.all(np.isfinite(e.per_part)) and np.isfinite(e.lost_flux)
    bi = _stats([e.flux for e in est])
    fw = _stats([forward_pass(scene, tracer, photons, 4, i).flux for i in range(passes)])
    return bi, fw


def _covers(a, b, k=3.0, floor=0.0):
    return abs(a[0] - b[0]) <= k * math.hypot(a[1], b[1]) + floor


def test_a_0_05_degree_gaussian_lobe():
    bi, fw = _bidir_vs_forward(singlet_barrel(make_bsdf("gaussian", reflectance=0.1, half_width_deg=0.05)), spp=2)
    assert bi[0] > 0 and _covers(bi, fw), (bi, fw)


@pytest.mark.parametrize("rho", [1e-6, 1.0])
def test_extreme_reflectance(rho):
    bi, fw = _bidir_vs_forward(singlet_barrel(make_bsdf("lambertian", reflectance=rho)))
    assert bi[0] > 0 and _covers(bi, fw), (bi, fw)


@pytest.mark.xfail(reason="issue 13 item 10: on axis the bidirectional reads ~1e-4 against forward ~1e-5; "
                          "this comparison passed only on forward's one-photon error bar (est-bias replaces it)",
                   strict=False)
def test_sun_exactly_on_axis():
    """The on-axis beam passes the stop and focuses inside the field: nothing scatters, 0 = 0 exactly."""
    bi, fw = _bidir_vs_forward(singlet_barrel(make_bsdf("lambertian", reflectance=0.1), off_axis_deg=0.0))
    assert _covers(bi, fw), (bi, fw)


def test_sun_at_89_degrees_is_finite_and_converging():
    """At 89° light grazes into the barrel mouth: a rare event for photons reaching the detector
    (the forward comparison is the slow test below), routine for the view map."""
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.1), off_axis_deg=89.0)
    tracer = Tracer(scene)
    m, se = _stats([bidirectional_pass(scene, tracer, 50_000, 3, i, 1.0, samples_per_pixel=32).flux for i in range(6)])
    assert m > 0 and se < 0.25 * m


@pytest.mark.slow
def test_sun_at_89_degrees_agrees_with_forward():
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.1), off_axis_deg=89.0)
    tracer = Tracer(scene)
    bi = _stats([bidirectional_pass(scene, tracer, 50_000, 3, i, 1.0, samples_per_pixel=32).flux for i in range(8)])
    fw = _stats([forward_pass(scene, tracer, 1_000_000, 4, i).flux for i in range(8)])
    assert _covers(bi, fw), (bi, fw)


def test_hit_points_on_the_50_um_diaphragm_edge():
    """Case 1 geometry: only the edge's channel lights up, and halving the edge halves it."""
    out = {}
    for width in (0.05, 0.025):
        scene = double_gauss_case(1, pixels=(12, 12), edge_width=width)
        tracer = Tracer(scene)
        est = [bidirectional_pass(scene, tracer, 200_000, 5, i, 1.0, samples_per_pixel=400) for i in range(4)]
        names = est[0].part_names
        for e in est:
            assert np.all(np.isfinite(e.image))
            lit = {n for n, f in zip(names, e.part_flux) if f > 0}
            assert lit <= {"diaphragm"}
        out[width] = _stats([e.flux for e in est])
    (m1, s1), (m2, s2) = out[0.05], out[0.025]
    assert m1 > 0 and m2 > 0
    ratio = m2 / m1
    ratio_se = ratio * math.hypot(s1 / m1, s2 / m2)
    assert abs(ratio - 0.5) < 3 * ratio_se + 0.05, (ratio, ratio_se)


def test_pixels_that_see_no_scatterer_are_zero_and_the_summary_is_finite(tmp_path):
    scene = double_gauss_case(1, pixels=(8, 8))
    tracer = Tracer(scene)
    acc = Accumulator.empty((8, 8), bidirectional_pass(scene, tracer, 10, 0, 0, 1.0).part_names,
                            scene.detector.pixel_area)
    for i in range(3):
        acc.add(bidirectional_pass(scene, tracer, 20_000, 9, i, 1.0, samples_per_pixel=2), i)
    assert np.all(np.isfinite(acc.mean_image)) and np.all(acc.mean_image >= 0)
    assert np.all(np.isfinite(acc.std_error_image))
    summary = build_summary(acc, method="bidirectional", seed=9, effects_ran=["scatter"], effects_skipped=[],
                            time_s=1.0, aperture_flux_mm2=2000.0, input_hash="x",
                            estimator_settings=EstimatorSettings().as_dict())
    write_run(tmp_path, acc, summary)  # json.dumps(allow_nan=False) would raise on any NaN/Inf


def test_radius_after_10000_passes_still_covers_the_analytic_value():
    """s_10000 ≈ 0.26: tiny radii, few photons per hit point — noisier, still unbiased and finite."""
    th = math.radians(30)
    d = (math.sin(th), 0, -math.cos(th))
    scene = PlanarScene([Face((0, 0, 0), (0, 0, 1), (1, 0, 0), (100.0, 0), "plate", disc=True)],
                        [make_bsdf("lambertian", reflectance=0.3)], Detector(2.0, 2.0, 4, 4, 50.0),
                        Collimated(d, (-300 * d[0], 0, 300 * math.cos(th)), 120.0))
    tracer = PlanarTracer(scene)
    s = radius_scale(9999)
    vals = [bidirectional_pass(scene, tracer, 50_000, 2, 9990 + i, s, samples_per_pixel=64).image.mean()
            for i in range(8)]
    mean, se = _stats(vals)
    expected = 0.3 * math.cos(th) * 100**2 / (100**2 + 50**2)
    assert abs(mean - expected) < 3 * se + 0.01 * expected, (mean, se, expected)
