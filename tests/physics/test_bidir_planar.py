"""The bidirectional pass on planar scenes with analytic answers (no optics, no Embree).

The planar world (tests/integrators/planar.py) is traced in numpy, so these tests pin
the integrator's own factors — backward weights, 1/S, π r², Φ = A_S/N, the face test,
the last-vertex rule for glossy lobes — against radiometry computed here by hand or by
an independent quadrature.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
from planar import Collimated, Detector, Face, PlanarScene, PlanarTracer  # noqa: E402

from lensmount.integrators.bidirectional import bidirectional_pass  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402

THETA = math.radians(30.0)
SUN = (math.sin(THETA), 0.0, -math.cos(THETA))  # travelling down onto plates facing +z


def _beam(centre, radius):
    c = np.asarray(centre, float) - 300.0 * np.asarray(SUN)
    return Collimated(SUN, tuple(c), radius)


def _run(scene, passes, photons, spp, **kw):
    tracer = PlanarTracer(scene)
    est = [bidirectional_pass(scene, tracer, photons, 11, i, kw.pop("scale", 1.0) if False else 1.0,
                              samples_per_pixel=spp, **kw) for i in range(passes)]
    for e in est:
        assert np.all(np.isfinite(e.image)) and np.all(np.isfinite(e.per_part))
    means = np.array([e.image.mean() for e in est])
    return means.mean(), means.std(ddof=1) / math.sqrt(passes), est


def _plate_scene(rho, a=100.0, D=50.0):
    return PlanarScene([Face((0, 0, 0), (0, 0, 1), (1, 0, 0), (a, 0), "plate", disc=True)],
                       [make_bsdf("lambertian", reflectance=rho)], Detector(2.0, 2.0, 4, 4, D),
                       _beam((0, 0, 0), 1.2 * a))


@pytest.mark.parametrize("connect", [False, True])
def test_lambertian_disc_seen_on_axis(connect):
    """E/E_sun = ρ cos θ_i · a² / (a² + D²) (radiance ρE cosθ/π times the disc's projected solid angle),
    counted by the gather, or by each photon's connection to the detector (the disc is seen straight)."""
    rho, a, D = 0.3, 100.0, 50.0
    mean, se, _ = _run(_plate_scene(rho, a, D), 6, 100_000, 256, connect_direct_view=connect)
    expected = rho * math.cos(THETA) * a * a / (a * a + D * D)
    assert abs(mean - expected) < 3 * se + 0.005 * expected, (mean, se, expected)
    assert se < 0.01 * expected


@pytest.mark.parametrize("rho", [1e-6, 1.0])
def test_extreme_reflectances_stay_finite_and_linear(rho):
    mean, se, est = _run(_plate_scene(rho), 3, 50_000, 64)
    expected = rho * math.cos(THETA) * 0.8
    assert math.isfinite(mean) and abs(mean - expected) < 4 * se + 0.01 * expected


def test_thin_edge_channel_is_not_fed_by_the_plate_beside_it():
    """A 50 µm strip (ρ = 0.1) beside a bright plate (ρ = 0.9), coplanar, seen from 5 mm.

    The strip's channel must equal its own radiance times its view factor (quadrature
    here); a gather that ignored faces would add the plate's nine-times-brighter photons.
    """
    w, length, D = 0.05, 4.0, 5.0
    strip = Face((0, 0, 0), (0, 0, 1), (0, 1, 0), (length / 2, w / 2), "edge")
    plate = Face((0, -(w / 2 + 2.0), 0), (0, 0, 1), (1, 0, 0), (3.0, 2.0), "plate")
    scene = PlanarScene([strip, plate], [make_bsdf("lambertian", reflectance=0.1),
                                          make_bsdf("lambertian", reflectance=0.9)],
                        Detector(0.4, 0.4, 2, 2, D), _beam((0, 0, 0), 5.0))
    tracer = PlanarTracer(scene)
    est = [bidirectional_pass(scene, tracer, 400_000, 3, i, 1.0, samples_per_pixel=40_000) for i in range(4)]
    edge = np.array([e.per_part[0].mean() for e in est])
    # Quadrature of ∫ L cos θ_y cos θ_x / r² dA over the strip, averaged over the detector.
    L = 0.1 * math.cos(THETA) / math.pi
    ys = np.linspace(-length / 2, length / 2, 2001)
    xs = np.linspace(-w / 2, w / 2, 11)
    gx, gy = np.meshgrid(xs, ys)
    e_det = []
    for px in (-0.1, 0.1):
        for py in (-0.1, 0.1):
            r2 = (gx - px) ** 2 + (gy - py) ** 2 + D * D
            e_det.append(np.trapezoid(np.trapezoid(L * D * D / r2**2, xs, axis=1), ys))
    expected = float(np.mean(e_det))
    se = edge.std(ddof=1) / 2
    assert abs(edge.mean() - expected) < 3 * se + 0.03 * expected, (edge.mean(), se, expected)


def _glossy_scene(half_width_deg, rho=0.05, D=50.0):
    """Plate with a Gaussian lobe, shifted so its specular reflection of the beam lands on the detector."""
    x0 = -D * math.tan(THETA)
    return PlanarScene([Face((x0, 0, 0), (0, 0, 1), (1, 0, 0), (20.0, 20.0), "mount")],
                       [make_bsdf("gaussian", reflectance=rho, half_width_deg=half_width_deg)],
                       Detector(4.0, 4.0, 4, 4, D), _beam((x0, 0, 0), 30.0))


def _glossy_quadrature(bsdf, D=50.0, n=600):
    x0 = -D * math.tan(THETA)
    xs = np.linspace(x0 - 20, x0 + 20, n)
    ys = np.linspace(-20, 20, n)
    gx, gy = np.meshgrid(xs, ys)
    p = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    wi = np.tile(-np.asarray(SUN), (len(p), 1))
    nrm = np.tile([0, 0, 1.0], (len(p), 1))
    vals = []
    for dx in np.linspace(-1.5, 1.5, 4):
        for dy in np.linspace(-1.5, 1.5, 4):
            v = np.array([dx, dy, D]) - p
            r = np.linalg.norm(v, axis=1)
            wo = v / r[:, None]
            f = bsdf.eval(wi, wo, nrm)
            integrand = f * math.cos(THETA) * wo[:, 2] * wo[:, 2] / r**2
            vals.append(integrand.sum() * (xs[1] - xs[0]) * (ys[1] - ys[0]))
    return float(np.mean(vals))


def test_glossy_rule_gather_and_photon_paths_agree_on_a_5_degree_lobe():
    """5° lobe: gathered at hit points (threshold 2°) and followed by photons (threshold 10°)
    give the same detector irradiance, and both match a quadrature of the lobe."""
    scene = _glossy_scene(5.0)
    expected = _glossy_quadrature(scene.bsdf_of_tag[0])
    g_mean, g_se, _ = _run(scene, 6, 50_000, 256, glossy_threshold_deg=2.0)
    f_mean, f_se, _ = _run(scene, 6, 200_000, 1, glossy_threshold_deg=10.0)
    assert abs(g_mean - expected) < 3 * g_se + 0.01 * expected, (g_mean, g_se, expected)
    assert abs(f_mean - expected) < 3 * f_se + 0.01 * expected, (f_mean, f_se, expected)


def test_a_0_05_degree_lobe_is_followed_by_photons_and_matches_the_mirror_image():
    """A 0.05° lobe is nearly a mirror: the reflected beam's irradiance on the detector is
    albedo(θ_i) · cos θ_r (E_sun = 1), uniform over the small detector."""
    scene = _glossy_scene(0.05)
    bsdf = scene.bsdf_of_tag[0]
    albedo = float(bsdf.albedo(-np.asarray([SUN]), np.array([[0, 0, 1.0]]))[0])
    mean, se, est = _run(scene, 6, 100_000, 16)
    expected = albedo * math.cos(THETA)
    assert abs(mean - expected) < 3 * se + 0.01 * expected, (mean, se, expected)


def _disc_view_factor(x, y, a, h):
    """View factor from a detector element at (x, y), parallel to a disc of radius a at height h on
    its axis: ½ [1 − (h² + r² − a²) / √((h² + r² + a²)² − 4 r² a²)]."""
    r2 = x * x + y * y
    return 0.5 * (1.0 - (h * h + r2 - a * a) / np.sqrt((h * h + r2 + a * a) ** 2 - 4.0 * r2 * a * a))


@pytest.mark.parametrize("pitch", [1, 2])
def test_a_coarse_view_map_reads_every_pixel(pitch):
    """Every pixel's irradiance from a wide Lambertian disc (ρE cosθ/π times the disc's view factor
    from that pixel), with the view map sampling blocks of pitch × pitch pixels: on a 3 × 3 detector
    the 2 × 2 blocks are cut at its right and top edges, so a block weight that ignored the cut
    (1.5–4× too much in the edge pixels) or a hit point put in the block's first pixel (others
    empty) fails here."""
    rho, a, D = 0.4, 200.0, 20.0
    scene = PlanarScene([Face((0, 0, 0), (0, 0, 1), (1, 0, 0), (a, 0), "plate", disc=True)],
                        [make_bsdf("lambertian", reflectance=rho)], Detector(24.0, 24.0, 3, 3, D),
                        _beam((0, 0, 0), 1.2 * a))
    _, _, est = _run(scene, 8, 30_000, 400, connect_direct_view=False, view_map_pitch=pitch)
    images = np.array([e.image for e in est])
    mean = images.mean(axis=0)
    total_se = images.sum(axis=(1, 2)).std(ddof=1) / math.sqrt(len(images))
    # the pixel average of ρ cos θ · F by a 40 × 40 midpoint rule over each 8 mm pixel
    u = (np.arange(40) + 0.5) / 40 * 8.0
    expected = np.array([[rho * math.cos(THETA) * _disc_view_factor(*np.meshgrid(-12.0 + 8.0 * ix + u,
                                                                               -12.0 + 8.0 * iy + u), a, D).mean()
                          for ix in range(3)] for iy in range(3)])
    assert np.all(np.abs(mean / expected - 1.0) < 0.2), mean / expected
    assert abs(mean.sum() - expected.sum()) < 4 * total_se + 0.01 * expected.sum(), (mean.sum(), expected.sum())
