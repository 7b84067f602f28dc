"""Paraxial data against independent figures: the reference lens computed by another
optical design package, and textbook thick-lens / Gaussian-imaging formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lensmount.optics.glass import refractive_index
from lensmount.optics.paraxial import marginal_heights, paraxial
from lensmount.optics.prescription import Aperture, Prescription, Surface

# reference/double-gauss-360.md: figures from an independent optical design package.
REF_EFL, REF_EPD, REF_EP_Z, REF_XPD = 360.013, 51.430, 208.48, 58.96


def test_reference_lens_matches_the_independent_package(double_gauss):
    p = paraxial(double_gauss)
    assert p.efl == pytest.approx(REF_EFL, rel=1e-4)        # ± 0.01 %
    assert p.epd == pytest.approx(REF_EPD, abs=0.0015)      # given to 3 decimals
    assert p.f_number == pytest.approx(7.0, abs=1e-12)      # the file's f/7, by definition EFL/EPD
    assert p.entrance_pupil_z == pytest.approx(REF_EP_Z, abs=0.005)
    assert p.exit_pupil_diameter == pytest.approx(REF_XPD, abs=0.005)


def test_reference_lens_image_plane_is_the_paraxial_focus(double_gauss):
    # The reference table's last thickness is "to paraxial image".
    p = paraxial(double_gauss)
    assert p.image_z == pytest.approx(double_gauss.image_z, abs=1e-3)
    assert p.bfl == pytest.approx(221.3551296, abs=1e-3)


def thick_lens(n, r1, r2, t):
    """Lensmaker's equation for a thick lens in air and its back focal length."""
    power = (n - 1.0) * (1.0 / r1 - 1.0 / r2 + (n - 1.0) * t / (n * r1 * r2))
    f = 1.0 / power
    return f, f * (1.0 - (n - 1.0) * t / (n * r1))


@pytest.mark.parametrize("r1, r2, t", [(50.0, -80.0, 8.0), (30.0, 200.0, 5.0), (-40.0, -25.0, 6.0),
                                       (60.0, math.inf, 4.0)])
def test_thick_lens_focal_lengths_match_the_lensmaker_formula(make_singlet, r1, r2, t):
    lens = make_singlet(r1, r2, t)
    n = float(refractive_index("N-BK7", lens.primary_wavelength_um))
    f, bfl = thick_lens(n, r1, r2, t)
    p = paraxial(lens)
    assert p.efl == pytest.approx(f, rel=1e-12)
    assert p.bfl == pytest.approx(bfl, rel=1e-12)


def test_exit_pupil_of_a_front_stop_follows_gaussian_imaging(make_singlet):
    r1, r2, t, gap = 50.0, -80.0, 8.0, 20.0
    lens = make_singlet(r1, r2, t, gap=gap, epd=12.0)
    n = float(refractive_index("N-BK7", lens.primary_wavelength_um))
    f, _ = thick_lens(n, r1, r2, t)
    # principal planes from the thick-lens formulas (textbook, Hecht 6.2)
    z1, z2 = gap, gap + t                               # lens vertices
    h_front = z1 - f * (n - 1.0) * t / (n * r2)
    h_back = z2 - f * (n - 1.0) * t / (n * r1)
    s = 0.0 - h_front                                   # stop at z = 0, object distance (negative)
    s_img = 1.0 / (1.0 / f + 1.0 / s)                   # 1/s' - 1/s = 1/f
    p = paraxial(lens)
    assert p.entrance_pupil_z == pytest.approx(0.0, abs=1e-12)   # nothing in front of the stop
    assert p.epd == 12.0 and p.stop_semi_diameter == pytest.approx(6.0)
    assert p.exit_pupil_z == pytest.approx(h_back + s_img, rel=1e-10)
    assert p.exit_pupil_diameter == pytest.approx(12.0 * abs(s_img / s), rel=1e-10)


def test_f_number_aperture_sets_the_entrance_pupil(make_singlet):
    lens = make_singlet()
    f = paraxial(lens).efl
    fno = Prescription(lens.surfaces, Aperture("fno", 4.0))
    assert paraxial(fno).epd == pytest.approx(f / 4.0, rel=1e-14)


def test_rear_stop_entrance_pupil_is_the_stop_seen_through_the_lens(make_singlet):
    # Stop 15 mm behind a thin-ish lens: seen from the object side it is imaged by the
    # lens used backwards; Gaussian imaging about the principal planes gives its position.
    r1, r2, t, d = 50.0, -80.0, 8.0, 15.0
    surfaces = (Surface(r1, t, "N-BK7"), Surface(r2, d), Surface(math.inf, 60.0, is_stop=True))
    lens = Prescription(surfaces, Aperture("epd", 10.0))
    n = float(refractive_index("N-BK7", lens.primary_wavelength_um))
    f, _ = thick_lens(n, r1, r2, t)
    h_front = 0.0 - f * (n - 1.0) * t / (n * r2)
    h_back = t - f * (n - 1.0) * t / (n * r1)
    s = (t + d) - h_back                                # stop measured from H' (positive: to the right)
    # reversed light: object at distance s in front of H' images to s' behind H (to the left)
    s_img = 1.0 / (1.0 / f - 1.0 / s)
    p = paraxial(lens)
    assert p.entrance_pupil_z == pytest.approx(h_front - s_img, rel=1e-10)


def test_marginal_heights_start_at_the_pupil_and_reach_zero_at_focus(double_gauss):
    h = marginal_heights(double_gauss)
    p = paraxial(double_gauss)
    assert h[0] == pytest.approx(p.epd / 2)
    assert h[double_gauss.stop_index] == pytest.approx(p.stop_semi_diameter)
    assert np.all(np.isfinite(h))


def test_afocal_system_gives_finite_numbers(make_plate):
    p = paraxial(make_plate())
    for v in (p.efl, p.bfl, p.exit_pupil_z, p.exit_pupil_diameter, p.image_z):
        assert math.isfinite(v)


def _mirror_lens(surfaces, epd=20.0):
    from lensmount.optics.prescription import Aperture, Prescription

    return Prescription(surfaces=tuple(surfaces), aperture=Aperture("epd", epd), wavelengths_um=(0.55,))


def test_concave_mirror_and_cassegrain_focal_lengths_follow_the_mirror_formulas():
    from lensmount.optics.prescription import Surface

    # one concave mirror, R = -200: f = |R| / 2 = 100, focus 100 mm in front of it (light returns along -z)
    single = _mirror_lens([Surface(radius=-200.0, thickness=-100.0, mirror=True, is_stop=True)])
    par = paraxial(single)
    assert abs(par.efl) == pytest.approx(100.0, rel=1e-12)
    assert par.image_z == pytest.approx(-100.0, rel=1e-12)
    # Cassegrain: primary R1 = -400 (f1 = 200), secondary R2 = -150 (convex to the returning light,
    # f2 = -75), separation d = 150: f = f1 f2 / (f1 + f2 - d) = 200 * -75 / (200 - 75 - 150) = 600
    cass = _mirror_lens([Surface(radius=-400.0, thickness=-150.0, mirror=True, is_stop=True),
                         Surface(radius=-150.0, thickness=200.0, mirror=True)])
    par = paraxial(cass)
    assert abs(par.efl) == pytest.approx(600.0, rel=1e-12)
    # Gaussian imaging at the secondary (real-positive mirror convention): the primary's focus lies
    # 50 mm beyond it (virtual object, s = -50), f2 = -75: 1/s' = 1/f2 - 1/s = 1/150, a real image
    # 150 mm back towards +z, i.e. at z = 0 (the primary's vertex), magnification -s'/s = 3 = 600 / 200.
    assert par.bfl == pytest.approx(150.0, rel=1e-12)
    assert par.image_z == pytest.approx(0.0, abs=1e-9)


def test_a_paraboloid_mirror_brings_every_parallel_ray_to_its_focus():
    from lensmount.optics.prescription import Surface
    from lensmount.optics.realrays import trace

    lens = _mirror_lens([Surface(radius=-200.0, conic=-1.0, thickness=-100.0, mirror=True, is_stop=True)], epd=80.0)
    h = np.linspace(-40.0, 40.0, 17)
    o = np.column_stack([np.zeros_like(h), h, np.full_like(h, -50.0)])
    d = np.tile([0.0, 0.0, 1.0], (len(h), 1))
    r = trace(lens, o, d)
    assert not r.vignetted.any()
    assert np.max(np.abs(r.image_points[:, 1])) < 1e-9          # all on axis at the paraxial focus
    assert np.all(r.directions[-1][:, 2] < 0.0)                  # travelling back towards -z
