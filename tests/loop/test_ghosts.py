"""Ghost analysis against paraxial hand calculations and Fresnel at normal incidence."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from lensmount.loop.ghosts import ghost_report
from lensmount.integrators.estimate import film_channels
from lensmount.optics.glass import refractive_index
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.scene.build import optical_surfaces
from lensmount.scene.scene import Effects
from lensmount.physics.detector import Detector
from lensmount.physics.interfaces import parse_coating
from lensmount.physics.sources import CollimatedSource, EmissionDisc

WL = 0.5875618
R1, T, H = 51.68, 6.0, 1.5  # a plano-convex N-BK7 singlet (f ≈ 100 mm) stopped down to f/33: paraxial
LOSSLESS = Effects(absorption=False)  # Fresnel products by hand: the glass's bulk absorption off


def _scene(coating: str, detector_mm: float = 60.0, pixels: int = 200, off_axis_deg: float = 0.0):
    lens = Prescription((Surface(R1, T, "N-BK7", is_stop=True, clear_semi_diameter=H, mechanical_semi_diameter=H),
                         Surface(math.inf, 96.0, "AIR", clear_semi_diameter=H, mechanical_semi_diameter=H)),
                        Aperture("epd", 2 * H), (WL,), (1.0,), 0, (0.0,), "singlet")
    wl = np.array([WL])
    c = parse_coating(coating)
    source = CollimatedSource(off_axis_deg, 90.0, EmissionDisc((0.0, 0.0, -100.0), 10.0))
    return SimpleNamespace(optical=optical_surfaces(lens, wl, lambda i, _: c), source=source,
                           detector=Detector(detector_mm, detector_mm, pixels, pixels, lens.image_z),
                           wavelengths_um=wl, entrance_pupil_area_mm2=math.pi * H * H,
                           effects=LOSSLESS), lens


def _paraxial_ghost_focus(n: float, z_back: float) -> float:
    """y–ω trace of the unfolded ghost: refract at S1, reflect at the flat S2, reflect at S1 from inside
    (a concave mirror of power 2nc in glass), out through the flat S2; returns the focus z."""
    c, tau = 1.0 / R1, T / n
    y, w = 1.0, -(n - 1.0) * c          # after S1
    y = y + 2 * tau * w                  # to the flat S2 and back to S1
    w = w - y * 2.0 * n * c              # the inside reflection at S1
    y = y + tau * w                      # to S2; refraction at a flat keeps ω
    return z_back + (-y / w)


def test_singlet_ghost_focus_matches_the_paraxial_hand_calculation():
    scene, lens = _scene("uncoated")
    report = ghost_report(scene)
    assert [(g.first, g.second) for g in report.pairs] == [(1, 2)]
    n = float(refractive_index("N-BK7", np.array([WL]))[0])
    z_focus = _paraxial_ghost_focus(n, T)
    expected = z_focus - lens.image_z
    assert expected == pytest.approx(-85.6, abs=1.0)  # the hand calculation itself, in round numbers
    assert report.pairs[0].focus_from_detector_mm == pytest.approx(expected, rel=2e-3)


def test_singlet_ghost_flux_is_the_fresnel_product_at_normal_incidence():
    scene, _ = _scene("uncoated", detector_mm=200.0, pixels=100)
    g = ghost_report(scene).pairs[0]
    n = float(refractive_index("N-BK7", np.array([WL]))[0])
    r = ((n - 1.0) / (n + 1.0)) ** 2
    # in through S1 (1 − R), R at S2 inside, R at S1 inside, out through S2 (1 − R); f/33: angles < 2°
    assert g.fraction == pytest.approx((1 - r) ** 2 * r * r, rel=2e-3)
    assert g.share == 1.0


def test_order_3_adds_the_four_reflection_ghost_with_its_fresnel_product():
    """Singlet, order 3: besides the pair, the one four-reflection route (S2, S1, S2, S1: twice round the
    glass) reaches the detector with (1 − R)² R⁴ of the pupil's light at normal incidence (f/33)."""
    scene, _ = _scene("uncoated", detector_mm=400.0, pixels=100)
    n = float(refractive_index("N-BK7", np.array([WL]))[0])
    r = ((n - 1.0) / (n + 1.0)) ** 2
    report = ghost_report(scene, order=3)
    routes = {g.surfaces: g for g in report.pairs}
    assert set(routes) == {(2, 1), (2, 1, 2, 1)} and report.order == 3
    assert routes[(2, 1, 2, 1)].fraction == pytest.approx((1 - r) ** 2 * r ** 4, rel=2e-3)
    assert routes[(2, 1)].fraction == pytest.approx((1 - r) ** 2 * r ** 2, rel=2e-3)
    assert routes[(2, 1, 2, 1)].label == "2→1→2→1" and routes[(2, 1)].label == "1–2"


def test_perfect_ar_means_no_ghost_and_no_rays_traced(monkeypatch):
    import lensmount.loop.ghosts as ghosts

    def fail(*args, **kwargs):
        raise AssertionError("a pair with no reflectance was traced")

    monkeypatch.setattr(ghosts, "trace_routes", fail)
    scene, _ = _scene("perfect-ar")
    report = ghost_report(scene)
    assert report.pairs == [] and report.skipped == [(1, 2)] and report.total_fraction == 0.0


def test_a_constant_reflectance_scales_as_its_square():
    a = ghost_report(_scene("R=0.01", detector_mm=200.0, pixels=100)[0]).pairs[0].fraction
    b = ghost_report(_scene("R=0.02", detector_mm=200.0, pixels=100)[0]).pairs[0].fraction
    assert b / a == pytest.approx((0.02 / 0.01) ** 2 * (0.98 / 0.99) ** 2, rel=1e-9)


def test_source_behind_the_lens_gives_an_empty_report():
    scene, _ = _scene("uncoated", off_axis_deg=120.0)
    assert ghost_report(scene).pairs == []


@pytest.mark.slow
def test_ghost_report_agrees_with_the_forward_estimators_ghost_channel():
    """The deterministic pair trace against stochastic Fresnel branching in the full tracer (an independent
    code path: Embree mesh, the tracer's own refraction and Fresnel sampling), on an uncoated singlet in a
    black barrel. Higher-order ghosts (four reflections, ~R² smaller) are inside the forward error bar."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
    from lens_scenes import singlet_barrel

    from lensmount.integrators.forward import forward_pass
    from lensmount.physics.bsdf import make_bsdf
    from lensmount.trace.tracer import Tracer

    scene = singlet_barrel(make_bsdf("absorber"), off_axis_deg=2.0, pixels=(40, 40), detector_mm=60.0,
                           ghosts=True, coating="uncoated")
    tracer = Tracer(scene)
    report = ghost_report(scene, tracer)
    ghost = film_channels(scene).index("ghosts")
    flux = [forward_pass(scene, tracer, 1_500_000, 7, i, ghost_routes=False).part_flux[ghost] for i in range(8)]
    aperture = scene.entrance_pupil_area_mm2 * math.cos(math.radians(2.0))
    mean, se = np.mean(flux) / aperture, np.std(flux, ddof=1) / math.sqrt(len(flux)) / aperture
    assert report.total_fraction == pytest.approx(mean, abs=4 * se)
    assert se < 0.1 * mean  # the comparison has teeth: without the barrel the report reads ~6x more
    assert abs(ghost_report(scene).total_fraction - mean) > 10 * se


DOUBLET = [(60.0, 4.0, "N-BK7"), (-45.0, 1.0, "AIR"), (-44.0, 2.5, "F2"), (-150.0, None, "AIR")]  # air-spaced


def _paraxial_route(n_glass: list[float], reflect_at: list[int]):
    """Lab-frame paraxial trace (slopes m = dy/dz, surfaces at their vertices) of a unit-height ray
    parallel to the axis, reflecting at the 0-based surfaces `reflect_at` in that order.
    Refraction keeps n (m + c y) (the tangential direction); reflection turns m into −m − 2 c y.
    Returns (y, m, z) after the last surface and the Fresnel product (normal incidence)."""
    z = np.cumsum([0.0] + [t for _, t, _ in DOUBLET[:-1]])
    c = [1.0 / r for r, _, _ in DOUBLET]
    n = [1.0] + n_glass  # n[k]: in front of surface k; n[k + 1]: behind it
    y, m, zc, k, step, todo, product = 1.0, 0.0, 0.0, 0, 1, list(reflect_at), 1.0
    while k < len(DOUBLET):
        assert k >= 0, "the route leaves through the front"
        y, zc = y + m * (z[k] - zc), z[k]
        n1, n2 = (n[k], n[k + 1]) if step > 0 else (n[k + 1], n[k])
        r = ((n1 - n2) / (n1 + n2)) ** 2
        if todo and todo[0] == k:
            todo.pop(0)
            m, step, product = -m - 2.0 * c[k] * y, -step, product * r
        else:
            m, product = (n1 * (m + c[k] * y) - n2 * c[k] * y) / n2, product * (1.0 - r)
        k += step
    return y, m, zc, product


def test_doublet_strongest_ghost_and_its_focus_match_the_paraxial_hand_calculation():
    """Uncoated air-spaced doublet at f/33 on axis: by hand, each ghost (i, j) is a y–u trace of the
    two-reflection path; a defocused ghost spreads the pupil's light over a disc of radius |y_det|
    (per unit entrance height), so its irradiance is R-product / y_det². The report's first pair
    (ranked by peak irradiance) must be the hand calculation's, with the same focus."""
    n_glass = [float(refractive_index(m, np.array([WL]))[0]) for _, _, m in DOUBLET]
    y, m, z_last, _ = _paraxial_route(n_glass, [])
    bfl = -y / m
    lens = Prescription(tuple(Surface(r, t if t is not None else bfl, mat, is_stop=k == 0, clear_semi_diameter=H,
                                      mechanical_semi_diameter=H) for k, (r, t, mat) in enumerate(DOUBLET)),
                        Aperture("epd", 2 * H), (WL,), (1.0,), 0, (0.0,), "doublet")
    z_image = z_last + bfl
    assert lens.image_z == pytest.approx(z_image, abs=1e-9)
    hand = {}
    for j in range(4):
        for i in range(j):
            y, m, z_last, product = _paraxial_route(n_glass, [j, i])
            y_det = y + m * (z_image - z_last)
            hand[(i + 1, j + 1)] = (product / y_det ** 2, z_last - y / m - z_image, product)
    ranked = sorted(hand, key=lambda k: hand[k][0], reverse=True)
    assert ranked[0] == (2, 3) and hand[ranked[0]][0] > 10 * hand[ranked[1]][0]  # the hand result, round numbers
    assert hand[(2, 3)][1] == pytest.approx(-35.0, abs=0.1)

    wl = np.array([WL])
    c = parse_coating("uncoated")
    scene = SimpleNamespace(optical=optical_surfaces(lens, wl, lambda i, _: c),
                            source=CollimatedSource(0.0, 90.0, EmissionDisc((0.0, 0.0, -100.0), 10.0)),
                            detector=Detector(30.0, 30.0, 300, 300, z_image), wavelengths_um=wl,
                            entrance_pupil_area_mm2=math.pi * H * H, effects=LOSSLESS)
    report = ghost_report(scene, rays_across=61)
    top = report.pairs[0]
    assert (top.first, top.second) == ranked[0]
    assert top.focus_from_detector_mm == pytest.approx(hand[ranked[0]][1], rel=2e-3)
    assert top.fraction == pytest.approx(hand[ranked[0]][2], rel=1e-2)  # lattice over a round pupil: ~0.5 %
    assert top.peak_irradiance == pytest.approx(hand[ranked[0]][0], rel=0.3)  # a uniform disc by hand
