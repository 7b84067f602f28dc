"""Automatic clear semi-diameters and the beam envelope, checked by invariants of the
beam (every ray passes, some ray touches each rim) and by exact straight-line geometry."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lensmount.errors import InputError
from lensmount.optics import apertures
from lensmount.optics.apertures import beam_envelope, with_clear_semi_diameters
from lensmount.optics.paraxial import paraxial
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.optics.realrays import aim, pupil_rings, trace


def _full_beam(lens, spokes=90):
    fields = np.linspace(-lens.max_field_deg, lens.max_field_deg, 9)
    rays = []
    for wl in lens.wavelengths_um:
        o, d = aim(lens, fields, pupil_rings(3, spokes), wl)
        rays.append(trace(lens, o, d, wl))
    return rays


def test_automatic_semi_diameters_pass_the_whole_beam_and_touch_it(double_gauss):
    beam = _full_beam(double_gauss)
    assert not any(r.vignetted.any() for r in beam)
    peak = np.max([r.heights()[:-1].max(axis=1) for r in beam], axis=0)
    csd = np.array([s.clear_semi_diameter for s in double_gauss.surfaces])
    assert np.all(peak <= csd * (1 + 1e-9))
    # the rim is where the beam is (sampling differs: a few µm)
    np.testing.assert_allclose(peak, csd, atol=0.01)


def test_stop_semi_diameter_is_where_the_real_axial_ray_at_epd_over_2_crosses_the_stop(double_gauss):
    """The ray parallel to the axis at EPD/2, traced by hand here, sets the stop (not the paraxial
    height, 16.306 mm: the front group's spherical aberration moves the real ray 8 µm)."""
    stop = double_gauss.stop_index
    h = paraxial(double_gauss).epd / 2.0
    rim = trace(double_gauss, [[0.0, h, -5.0]], [[0.0, 0.0, 1.0]], clip=False)
    assert double_gauss.surfaces[stop].clear_semi_diameter == pytest.approx(rim.points[stop, 0, 1], rel=1e-12)
    assert abs(rim.points[stop, 0, 1] - paraxial(double_gauss).stop_semi_diameter) > 1e-3


@pytest.mark.parametrize("name, opticstudio", [
    ("thorlabs-ACL2520-A.zmx", 9.149889739468),      # a strong asphere before the stop: paraxially 6.808 mm
    ("US00583336-2-scaled.zmx", 4.215000499256)])    # paraxially 4.2508 mm
def test_stop_semi_diameter_is_opticstudios_automatic_stop_diam(name, opticstudio):
    """OpticStudio's automatic stop DIAM (flag 0, written in the file) is the real axial ray's height at
    EPD/2; B270's index (lensmount's table, not Zemax's catalogue) leaves 0.2 µm on ACL2520-A."""
    from lensmount.design.lens import load_lens
    from lensmount.optics.realrays import stop_semi_diameter

    p = load_lens(Path(__file__).parent / "corpus" / name)
    assert stop_semi_diameter(p) == pytest.approx(opticstudio, abs=5e-4)
    assert abs(paraxial(p).stop_semi_diameter - opticstudio) > 0.03


def test_margin_is_added_to_automatic_semi_diameters_only(double_gauss_raw):
    given = double_gauss_raw.surfaces[0]
    lens = double_gauss_raw.with_surfaces(
        [Surface(**{**given.__dict__, "clear_semi_diameter": 45.0})] + list(double_gauss_raw.surfaces[1:]))
    a = with_clear_semi_diameters(lens, 0.0)
    b = with_clear_semi_diameters(lens, 0.5)
    da = np.array([s.clear_semi_diameter for s in a.surfaces])
    db = np.array([s.clear_semi_diameter for s in b.surfaces])
    expected = np.full(len(da), 0.5)
    expected[0] = 0.0                         # given by the file
    expected[lens.stop_index] = 0.0           # the stop is the aperture itself
    np.testing.assert_allclose(db - da, expected, atol=1e-12)


def test_a_radius_too_small_for_the_beam_is_an_input_error():
    lens = Prescription((Surface(8.0, 3.0, "N-BK7", is_stop=True), Surface(-8.0, 20.0)),
                        Aperture("epd", 20.0))
    with pytest.raises(InputError) as err:
        with_clear_semi_diameters(lens)
    assert err.value.field == "surface[1].radius"


def test_envelope_in_front_of_the_lens_is_straight_collimated_beams(double_gauss):
    # Far in front, the widest ray is the lower rim ray of the largest field: its radius
    # grows by tan(theta_max) per mm travelled backwards.
    z = np.array([-300.0, -200.0])
    env = beam_envelope(double_gauss, z)
    assert env[0] - env[1] == pytest.approx(100.0 * math.tan(math.radians(5.0)), rel=1e-9)


def test_envelope_at_the_stop_is_the_stop_and_at_surfaces_the_clear_aperture(double_gauss):
    z = np.array(double_gauss.vertex_z)
    env = beam_envelope(double_gauss, z)
    stop = double_gauss.stop_index
    assert env[stop] == pytest.approx(double_gauss.surfaces[stop].clear_semi_diameter, rel=1e-7)
    # at a curved surface's vertex plane the beam is not yet (or no longer) at the glass;
    # but at the plane surfaces (4, 8: cemented planes) the rim is the clear aperture
    for i in (3, 7):
        assert env[i] == pytest.approx(double_gauss.surfaces[i].clear_semi_diameter, abs=0.01)


def test_envelope_bounds_every_ray(double_gauss):
    # independent rays (other pupil points and fields, including negative ones)
    rng = np.random.default_rng(7)
    fields = rng.uniform(-5.0, 5.0, 5)
    rho, phi = np.sqrt(rng.uniform(0, 1, 40)), rng.uniform(0, 2 * np.pi, 40)
    pupil = np.column_stack([rho * np.cos(phi), rho * np.sin(phi)])
    o, d = aim(double_gauss, fields, pupil)
    r = trace(double_gauss, o, d)
    pts = r.points[:-1].reshape(-1, 3)
    env = beam_envelope(double_gauss, pts[:, 2])
    assert np.all(np.hypot(pts[:, 0], pts[:, 1]) <= env + 1e-6)


@pytest.mark.slow
def test_envelope_is_converged_in_the_pupil_and_field_sampling(double_gauss):
    # a 4x denser pupil and 2x denser field sampling moves the envelope by < 0.05 mm
    z = np.linspace(-50.0, 520.0, 120)
    coarse = beam_envelope(double_gauss, z)
    old = apertures.ENVELOPE_SPOKES, apertures.ENVELOPE_RINGS, apertures.ENVELOPE_FIELDS
    try:
        apertures.ENVELOPE_SPOKES, apertures.ENVELOPE_RINGS, apertures.ENVELOPE_FIELDS = 720, 16, 21
        fine = beam_envelope(double_gauss, z)
    finally:
        apertures.ENVELOPE_SPOKES, apertures.ENVELOPE_RINGS, apertures.ENVELOPE_FIELDS = old
    assert np.all(fine >= coarse - 1e-9)
    assert np.max(fine - coarse) < 0.05


def test_envelope_is_finite_everywhere(double_gauss):
    z = np.array([-1e4, -1.0, 0.0, 150.91, 502.0, 1e4])
    env = beam_envelope(double_gauss, z)
    assert np.all(np.isfinite(env)) and np.all(env > 0)


def test_a_land_behind_the_stop_passes_the_field_beam_displaced_by_its_distance_times_the_slope():
    """Hand-traced: the stop a plane in air at z = 0, 20 mm in front of a singlet, object at infinity: in that
    gap every ray of field theta is straight and parallel, the ray through stop point p at p + z tan(theta) y.
    A diaphragm's land of radius a = EPD/2 (the axial rim ray's, parallel at a) from z0 to z1 behind the stop
    passes the rays inside a at both ends, so behind it the widest is the one leaving z1 at its rim:
    a + (z - z1) tan(theta); the beam aimed at the stop reaches a + z tan(theta). (It fails when the land's
    cut is not applied, and when only the stop-aimed rays are filtered: they sample the passed rim coarsely.)"""
    a, theta, z0, z1 = 5.0, 10.0, 4.0, 4.05
    lens = Prescription((Surface(math.inf, 20.0, is_stop=True), Surface(60.0, 5.0, "N-BK7"), Surface(-60.0, 50.0)),
                        Aperture("epd", 2 * a), field_angles_deg=(0.0, theta))
    t = math.tan(math.radians(theta))
    z = np.array([4.5, 8.0, 15.0])
    np.testing.assert_allclose(beam_envelope(lens, z), a + z * t, rtol=1e-9)
    np.testing.assert_allclose(beam_envelope(lens, z, (z0, z1, a)), a + (z - z1) * t, rtol=1e-9)
    assert beam_envelope(lens, [0.5 * (z0 + z1)], (z0, z1, a))[0] <= a + 1e-6   # inside the land: the land itself
