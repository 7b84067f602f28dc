"""Forward estimator against closed forms.

1. A Lambertian disc (radius a, reflectance ρ) lit by a collimated source at angle θ from its
   normal, seen by a small detector parallel to it at height h on its axis: the detector
   irradiance is E(r) = ρ E_sun cos θ F(r), with the configuration factor from a parallel
   disc to a point at radial offset r (Siegel & Howell, config. factor B-13):
       F = ½ [1 − (h² + r² − a²) / sqrt((h² + r² + a²)² − 4 r² a²)].
2. Doubling the emission disc's area A_S leaves the result unchanged (flux bookkeeping).
3. Same seed, same image; another pass, another (independent) image.
4. Direct light through a plane window: flux = E_sun · A_opening · cos θ · T², T from Fresnel.
"""

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.trace.geometry import make_scene, mech_scene, window  # noqa: E402
from lensmount.integrators.forward import forward_pass  # noqa: E402
from lensmount.scene import primitives  # noqa: E402
from lensmount.physics.sources import EmissionDisc  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402

A, H, RHO, THETA = 5.0, 10.0, 0.5, 120.0  # disc radius, detector height, reflectance, source angle (deg)
SIDE = 4.0  # detector side, mm; the detector's shadow (offset H tan 60° = 17 mm) misses the disc


def _disc_scene():
    plate = primitives.disk((0.0, 0.0, 0.0), A, segments=256, part="plate", finish="lambert")
    return mech_scene(plate, detector={"width_mm": SIDE, "height_mm": SIDE, "pixels": [2, 2], "z_mm": H},
                      source={"type": "collimated", "off_axis_deg": THETA, "azimuth_deg": 90.0},
                      finishes={"lambert": {"model": "lambertian", "reflectance": RHO}},
                      effects={"scatter": True, "direct": False}, assign={"*": "lambert"})


def _expected_pixel_irradiance():
    """Mean of E over each quadrant pixel (all four equal by symmetry), by quadrature."""
    g = (np.arange(200) + 0.5) / 200 * (SIDE / 2)
    x, y = np.meshgrid(g, g)
    r2 = x**2 + y**2
    f = 0.5 * (1 - (H**2 + r2 - A**2) / np.sqrt((H**2 + r2 + A**2) ** 2 - 4 * r2 * A**2))
    # The segmented disc has the area of a 256-gon, not of the circle: scale the incident flux.
    polygon = 0.5 * 256 * math.sin(2 * math.pi / 256) / math.pi
    return RHO * abs(math.cos(math.radians(THETA))) * f.mean() * polygon


def test_lambertian_disc_irradiance_matches_configuration_factor():
    scene = _disc_scene()
    tracer = Tracer(scene)
    passes = [forward_pass(scene, tracer, 300_000, seed=3, pass_index=i) for i in range(4)]
    est = passes[0]
    expected = _expected_pixel_irradiance()
    assert est.image.shape == (2, 2) and est.lost_flux == 0.0
    # Error bar from the spread of independent passes (batch means), as a run reports it.
    values = [e.image.mean() for e in passes]
    mean, err = np.mean(values), np.std(values, ddof=1) / 2.0
    assert abs(mean - expected) < 4 * err, (mean, err, expected)
    assert err < 0.02 * expected  # teeth: a 10 % bias (a lost cos θ or π would be far more) fails
    np.testing.assert_allclose(est.per_part.sum(axis=0), est.image)
    assert est.part_names == ["plate"]


def test_emission_disc_size_does_not_change_the_result():
    scene = _disc_scene()
    tracer = Tracer(scene)
    big_disc = EmissionDisc(scene.source.disc.centre, scene.source.disc.radius * math.sqrt(2.0))
    big = dataclasses.replace(scene, source=dataclasses.replace(scene.source, disc=big_disc))
    n = 200_000
    runs_small = [forward_pass(scene, tracer, n, seed=11, pass_index=i).flux for i in range(3)]
    runs_big = [forward_pass(big, tracer, 2 * n, seed=12, pass_index=i).flux for i in range(3)]
    s, b = np.mean(runs_small), np.mean(runs_big)
    err = math.hypot(np.std(runs_small, ddof=1) / math.sqrt(3), np.std(runs_big, ddof=1) / math.sqrt(3))
    assert abs(s - b) < 4 * err, (s, b, err)
    assert err < 0.05 * s  # a bookkeeping error (flux not ∝ A_S) would be a factor 2, ~ 50 σ


def test_same_seed_same_image_and_passes_differ():
    scene = _disc_scene()
    tracer = Tracer(scene)
    a = forward_pass(scene, tracer, 30_000, seed=5, pass_index=4)
    b = forward_pass(scene, tracer, 30_000, seed=5, pass_index=4)
    c = forward_pass(scene, tracer, 30_000, seed=5, pass_index=5)
    np.testing.assert_array_equal(a.image, b.image)
    assert not np.array_equal(a.image, c.image)
    # Chunking is bookkeeping only: smaller batches give the same mean within noise and the same flux units.
    d = forward_pass(scene, tracer, 30_000, seed=5, pass_index=4, batch=7_000)
    assert d.photons == 30_000 and abs(d.flux - a.flux) < 0.2 * a.flux


@pytest.mark.parametrize("theta", [0.0, 20.0])
def test_direct_light_through_a_window(theta):
    """Uncoated BK7 window, no ghosts: detector flux = A_opening cos θ T² (opening = the window's
    face, a 64-gon of radius 20, behind an absorbing plate with the same hole)."""
    p = window(semi_diameter=20.0)
    # An absorbing plate in front whose hole is exactly the window's 64-gon outline, so only
    # light through the window can reach the detector (photons passing outside the plate miss it).
    plate = primitives.tube(-2.0, -1.0, 20.0, 80.0, part="plate", kind="housing", finish="absorber", segments=64)
    mesh = primitives.lens_elements(p, [20.0, 20.0], rings=4, segments=64)
    mesh = type(mesh).concatenate([mesh, plate])
    scene = make_scene(p, mesh, detector={"width_mm": 80, "height_mm": 80, "pixels": [1, 1]},
                       source={"type": "collimated", "off_axis_deg": theta, "azimuth_deg": 0.0},
                       coatings={"default": "uncoated"}, effects={"direct": True, "scatter": False})
    est = forward_pass(scene, Tracer(scene), 100_000, seed=1, pass_index=0)
    n = float(scene.optical[0].n_after[0])
    from lensmount.physics.interfaces import Coating, reflectance
    c1 = math.cos(math.radians(theta))
    c2 = math.sqrt(1 - (math.sin(math.radians(theta)) / n) ** 2)
    r1 = reflectance(np.array([1.0]), np.array([n]), np.array([c1]), Coating("uncoated"), np.array([0.55]))[0]
    r2 = reflectance(np.array([n]), np.array([1.0]), np.array([c2]), Coating("uncoated"), np.array([0.55]))[0]
    # Photons through the 64-gon front face; the rim (5 mm thick) shadows part of it when tilted.
    polygon = 0.5 * 64 * math.sin(2 * math.pi / 64) * 20.0**2
    assert r1 == pytest.approx(r2, rel=1e-9)  # Stokes: the same reflectance both ways
    expected = polygon * c1 * (1 - r1) * (1 - r2)
    # Binomial error of the fraction of emission-disc photons that pass.
    frac = expected / scene.source.disc.area
    err = scene.source.disc.area * math.sqrt(frac * (1 - frac) / 100_000)
    if theta == 0.0:
        assert abs(est.flux - expected) < 4 * err, (est.flux, expected, err)
    else:
        # Tilted, the thin rim blocks a sliver: at most 5 mm·tan(θ') of the 40 mm diameter.
        assert expected * 0.9 < est.flux < expected + 4 * err
    assert est.part_names[-1] == "direct" and est.per_part[-1].sum() == pytest.approx(est.image.sum())


def test_ghost_channel_of_a_window():
    """Uncoated window at normal incidence, ghosts on: the unscattered light splits into the
    `direct` channel (no reflection: A T²) and the `ghosts` channel (2k reflections, k >= 1:
    A T² R² / (1 − R²)), the incoherent plate's series."""
    p = window(semi_diameter=20.0)
    plate = primitives.tube(-2.0, -1.0, 20.0, 80.0, part="plate", kind="housing", finish="absorber", segments=64)
    mesh = type(plate).concatenate([primitives.lens_elements(p, [20.0, 20.0], rings=4, segments=64), plate])
    scene = make_scene(p, mesh, detector={"width_mm": 80, "height_mm": 80, "pixels": [1, 1]},
                       source={"type": "collimated", "off_axis_deg": 0.0, "azimuth_deg": 0.0},
                       coatings={"default": "uncoated"}, effects={"direct": True, "ghosts": True, "scatter": False})
    n_photons = 400_000
    est = forward_pass(scene, Tracer(scene), n_photons, seed=2, pass_index=0)
    n = float(scene.optical[0].n_after[0])
    r = ((n - 1) / (n + 1)) ** 2
    area = 0.5 * 64 * math.sin(2 * math.pi / 64) * 20.0**2
    flux = dict(zip(est.part_names, est.part_flux))
    disc = scene.source.disc.area
    for name, expected in (("direct", area * (1 - r) ** 2), ("ghosts", area * (1 - r) ** 2 * r**2 / (1 - r**2))):
        frac = expected / disc
        err = disc * math.sqrt(frac * (1 - frac) / n_photons)
        assert abs(flux[name] - expected) < 4 * err, (name, flux[name], expected, err)
    assert flux["ghosts"] > 0


@pytest.mark.slow
def test_light_from_behind_through_an_open_back_is_not_dropped():
    """The sun at 150°, behind the entrance plane: no light enters the front, but a Lambertian
    disc (radius 25 mm, wider than the 10 mm front opening) lit from behind still scatters onto
    the detector's face. Against the configuration factor, as above."""
    a = 25.0
    plate = primitives.disk((0.0, 0.0, 0.0), a, segments=256, part="plate", finish="lambert")
    scene = mech_scene(plate, detector={"width_mm": SIDE, "height_mm": SIDE, "pixels": [1, 1], "z_mm": H},
                       source={"type": "collimated", "off_axis_deg": 150.0, "azimuth_deg": 90.0},
                       finishes={"lambert": {"model": "lambertian", "reflectance": RHO}},
                       effects={"scatter": True, "direct": False}, assign={"*": "lambert"})
    assert scene.source.entering_fraction == 0.0 and scene.source.no_light_enters
    tracer = Tracer(scene)
    values = [forward_pass(scene, tracer, 200_000, seed=5, pass_index=i).image.mean() for i in range(3)]
    g = (np.arange(200) + 0.5) / 200 * SIDE - SIDE / 2
    x, y = np.meshgrid(g, g)
    r2 = x**2 + y**2
    f = 0.5 * (1 - (H**2 + r2 - a**2) / np.sqrt((H**2 + r2 + a**2) ** 2 - 4 * r2 * a**2))
    expected = RHO * math.cos(math.radians(30.0)) * f.mean() * 0.5 * 256 * math.sin(2 * math.pi / 256) / math.pi
    mean, err = np.mean(values), np.std(values, ddof=1) / math.sqrt(3)
    assert abs(mean - expected) < 4 * err + 1e-3 * expected, (mean, err, expected)
    assert err < 0.05 * expected
