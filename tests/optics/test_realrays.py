"""Sequential real-ray trace against exact optics: plate displacement, the exact focus of
one refracting sphere, Snell's law, and the paraxial limit of the reference lens."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lensmount.optics.glass import refractive_index
from lensmount.optics.paraxial import paraxial
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.optics.realrays import aim, chief_ray, field_direction, marginal_ray, spot, stop_semi_diameter, trace
from lensmount.optics.snell import refract


def test_flat_plate_displaces_rays_by_the_textbook_formula(make_plate):
    d_plate = 10.0
    lens = make_plate(t=d_plate)
    n = float(refractive_index("N-BK7", lens.primary_wavelength_um))
    theta = np.radians([0.0, 5.0, 20.0, 40.0, 60.0, 80.0])
    d = field_direction(np.degrees(theta))
    o = np.zeros((len(theta), 3)) + [0.0, 0.0, -5.0]
    r = trace(lens, o, d, clip=False)
    assert not r.vignetted.any()
    out = r.points[-1]
    # the ray leaves parallel to itself ...
    np.testing.assert_allclose(r.directions[-1], d, atol=1e-14)
    # ... displaced perpendicular to itself by d sin(theta) (1 - cos(theta) / sqrt(n^2 - sin^2 theta))
    undeviated = o + d * ((out[:, 2] - o[:, 2]) / d[:, 2])[:, None]
    shift = out - undeviated
    perpendicular = np.abs(shift[:, 1] * d[:, 2] - shift[:, 2] * d[:, 1])
    expected = d_plate * np.sin(theta) * (1.0 - np.cos(theta) / np.sqrt(n * n - np.sin(theta) ** 2))
    np.testing.assert_allclose(perpendicular, expected, rtol=1e-12, atol=1e-13)


def test_single_sphere_focuses_each_zone_where_exact_geometry_says():
    # Parallel ray at height h onto a sphere of radius R (air -> n): incidence sin i = h/R,
    # refraction sin r = sin i / n; it crosses the axis at R + R sin r / sin(i - r).
    radius, n_glass = 40.0, 1.7
    lens = Prescription((Surface(radius, 200.0, "1.7/50", is_stop=True),), Aperture("epd", 20.0),
                        wavelengths_um=(0.5875618,))
    assert float(refractive_index("1.7/50", 0.5875618)) == pytest.approx(n_glass, abs=1e-14)
    h = np.array([0.01, 1.0, 5.0, 10.0, 20.0, 30.0])
    r = trace(lens, np.column_stack([np.zeros_like(h), h, np.full_like(h, -1.0)]),
              np.tile([0.0, 0.0, 1.0], (len(h), 1)), clip=False)
    p, d = r.points[0], r.directions[0]
    z_cross = p[:, 2] - p[:, 1] * d[:, 2] / d[:, 1]
    i = np.arcsin(h / radius)
    rr = np.arcsin(np.sin(i) / n_glass)
    np.testing.assert_allclose(z_cross, radius + radius * np.sin(rr) / np.sin(i - rr), rtol=1e-12)


def test_snell_law_holds_for_random_directions_and_normals():
    rng = np.random.default_rng(3)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    nrm = rng.normal(size=(2000, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    n1, n2 = 1.0, 1.6
    out, tir, _, _ = refract(d, nrm, np.full(len(d), n1 / n2))
    assert not tir.any()                     # from low to high index there is no TIR
    cross_in = np.linalg.norm(np.cross(d, nrm), axis=1)
    cross_out = np.linalg.norm(np.cross(out, nrm), axis=1)
    np.testing.assert_allclose(n1 * cross_in, n2 * cross_out, atol=1e-13)   # n sin i = n' sin r
    coplanar = np.einsum("ij,ij->i", np.cross(d, nrm), out)
    np.testing.assert_allclose(coplanar, 0.0, atol=1e-13)
    # back out again (high to low): beyond the critical angle it is TIR, flagged, and the light reflects
    back, tir2, _, _ = refract(d, nrm, np.full(len(d), n2 / n1))
    sin_i = cross_in
    np.testing.assert_array_equal(tir2, sin_i > n1 / n2)
    assert np.all(np.isfinite(back))
    mirrored = d - 2.0 * np.einsum("ij,ij->i", d, nrm)[:, None] * nrm
    np.testing.assert_allclose(back[tir2], mirrored[tir2], atol=1e-15)


def test_on_axis_marginal_ray_meets_paraxial_focus_within_the_spherical_aberration(double_gauss):
    par = paraxial(double_gauss)

    def focus_shift(rho):
        r = trace(double_gauss, [[0.0, rho * par.epd / 2, 0.0]], [[0.0, 0.0, 1.0]], clip=False)
        p, d = r.points[-2, 0], r.directions[-2, 0]
        return p[2] - p[1] * d[2] / d[1] - par.image_z

    shifts = np.array([focus_shift(rho) for rho in (0.01, 0.1, 0.2, 0.5, 1.0)])
    # paraxial limit: the zonal focus converges to the paraxial focus ...
    assert abs(shifts[0]) < 1e-4
    # ... with third-order spherical aberration, the shift grows as rho^2
    assert shifts[2] / shifts[1] == pytest.approx(4.0, rel=0.02)
    # the marginal ray misses the paraxial focus by no more than the third-order
    # estimate scaled from the 0.2 zone (higher orders within a factor 2), and the
    # blur it implies stays below a few Airy radii for this f/7 lens (1.22·λ·F# = 5 µm).
    third_order = shifts[2] / 0.04
    assert abs(shifts[4]) <= 2.0 * abs(third_order) + 1e-3
    assert abs(shifts[4]) < 1.0


def test_rays_outside_a_clear_aperture_are_vignetted_not_traced_through(double_gauss):
    # rays entering beyond surface 1's clear semi-diameter
    csd = double_gauss.surfaces[0].clear_semi_diameter
    h = np.array([0.0, 0.5 * csd, 0.999 * csd, 1.01 * csd, 1.5 * csd])
    o = np.column_stack([np.zeros_like(h), h, np.zeros_like(h)])
    r = trace(double_gauss, o, np.tile([0.0, 0.0, 1.0], (len(h), 1)))
    np.testing.assert_array_equal(r.vignetted, [False, False, True, True, True])
    np.testing.assert_array_equal(r.vignetted_at[3:], [0, 0])
    # the stopped rays are not traced further: their recorded points stay where they were
    # stopped (the launch point) and their intensity is zero; every number is finite
    assert np.all(r.points[:, 3:, 2] == 0.0)
    np.testing.assert_array_equal(r.intensity, [1, 1, 0, 0, 0])
    assert np.all(np.isfinite(r.points)) and np.all(np.isfinite(r.directions))
    # the 0.999 ray clears surface 1 but, far outside the on-axis pupil, a later
    # aperture (at the latest the stop) cuts it
    assert 1 <= r.vignetted_at[2] <= double_gauss.stop_index


def test_missing_a_sphere_and_total_internal_reflection_vignette_without_nan():
    # a ray higher than the radius misses the sphere; a steep ray inside glass meets TIR
    lens = Prescription((Surface(10.0, 5.0, "N-SF6", is_stop=True), Surface(math.inf, 20.0)),
                        Aperture("epd", 4.0))
    o = np.array([[0.0, 12.0, -1.0], [0.0, 9.9, -1.0], [0.0, 1.0, -1.0]])
    r = trace(lens, o, np.tile([0.0, 0.0, 1.0], (3, 1)), clip=False)
    assert r.vignetted_at[0] == 0            # missed surface 1
    assert r.vignetted_at[1] == 1            # TIR at the plane back face
    assert not r.vignetted[2]
    assert np.all(np.isfinite(r.points)) and np.all(np.isfinite(r.directions))


def test_aimed_rays_cross_the_stop_where_asked(double_gauss):
    pupil = np.array([[0.0, 0.0], [0.0, 1.0], [0.0, -1.0], [1.0, 0.0], [0.6, -0.3]])
    fields = [0.0, 3.5, 5.0]
    o, d = aim(double_gauss, fields, pupil)
    r = trace(double_gauss, o, d)
    assert not r.vignetted.any()
    r_stop = stop_semi_diameter(double_gauss)
    at_stop = r.points[double_gauss.stop_index, :, :2]
    np.testing.assert_allclose(at_stop, np.tile(pupil * r_stop, (3, 1)), atol=1e-8)


def test_chief_and_marginal_rays(double_gauss):
    chief = chief_ray(double_gauss, [0.0, 3.5, 5.0])
    np.testing.assert_allclose(chief.points[double_gauss.stop_index, :, :2], 0.0, atol=1e-9)
    f = paraxial(double_gauss).efl
    # image heights close to f tan(theta) (a double Gauss has well under 1 % distortion)
    np.testing.assert_allclose(chief.image_points[1:, 1], f * np.tan(np.radians([3.5, 5.0])), rtol=5e-3)
    assert chief.image_points[0, 1] == pytest.approx(0.0, abs=1e-12)
    marginal = marginal_ray(double_gauss, 0.0)
    assert marginal.points[double_gauss.stop_index, 0, 1] == pytest.approx(stop_semi_diameter(double_gauss))


def test_mirror_symmetric_fields_give_mirrored_rays(double_gauss):
    # field -4 deg at pupil (x, y) is the mirror image of field +4 deg at pupil (x, -y)
    o1, d1 = aim(double_gauss, [4.0], [[0.3, 0.8]])
    o2, d2 = aim(double_gauss, [-4.0], [[0.3, -0.8]])
    r = trace(double_gauss, np.vstack([o1, o2]), np.vstack([d1, d2]))
    np.testing.assert_allclose(r.points[:, 0, 1], -r.points[:, 1, 1], atol=1e-9)
    np.testing.assert_allclose(r.points[:, 0, 0], r.points[:, 1, 0], atol=1e-9)


def test_spot_is_small_on_axis_and_centred_on_the_chief_ray(double_gauss):
    s0 = spot(double_gauss, 0.0)
    assert s0.transmitted == 1.0
    assert s0.rms_radius < 0.05          # tens of µm for this lens
    assert abs(s0.x.mean()) < 1e-9 and abs(s0.y.mean()) < 1e-9
    s5 = spot(double_gauss, 5.0)
    assert abs(s5.y.mean() - s5.chief_y) < 0.1


def test_invalid_input_rays_are_dead_lanes_not_nan(double_gauss):
    o = np.array([[0.0, 1.0, 0.0], [np.nan, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, np.inf, 0.0]])
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    r = trace(double_gauss, o, d)
    np.testing.assert_array_equal(r.vignetted, [False, True, True, True])
    np.testing.assert_array_equal(r.vignetted_at[1:], [0, 0, 0])
    assert np.all(np.isfinite(r.points)) and np.all(np.isfinite(r.directions))
    empty = trace(double_gauss, np.zeros((0, 3)), np.zeros((0, 3)))
    assert empty.points.shape == (len(double_gauss.surfaces) + 1, 0, 3)


def test_cartesian_ellipsoid_focuses_every_zone_to_one_point():
    # A refracting ellipsoid of eccentricity 1/n (conic k = -1/n^2) images an axial point
    # at infinity without aberration onto its far focus, n R / (n - 1) behind the vertex
    # (Descartes' oval). Exercises the conic intersection and normal exactly.
    n_glass, radius = 1.7, 30.0
    lens = Prescription((Surface(radius, 500.0, "1.7/50", conic=-1.0 / n_glass**2, is_stop=True),),
                        Aperture("epd", 30.0))
    h = np.linspace(0.5, 16.0, 12)
    r = trace(lens, np.column_stack([0.6 * h, 0.8 * h, np.full_like(h, -2.0)]),
              np.tile([0.0, 0.0, 1.0], (len(h), 1)), clip=False)
    assert not r.vignetted.any()
    p, d = r.points[0], r.directions[0]
    s = -p[:, 1] / d[:, 1]                       # where each ray meets the axis
    focus = p + s[:, None] * d
    np.testing.assert_allclose(focus[:, 2], n_glass * radius / (n_glass - 1.0), rtol=1e-11)
    np.testing.assert_allclose(focus[:, 0], 0.0, atol=1e-9)


def test_even_asphere_hits_lie_on_the_surface_and_follow_snell():
    lens = Prescription((Surface(40.0, 6.0, "N-BK7", conic=-0.7, aspheric=(2e-6, -3e-9), is_stop=True),
                         Surface(-60.0, 50.0)), Aperture("epd", 20.0))
    rng = np.random.default_rng(11)
    o = np.column_stack([rng.uniform(-9, 9, 500), rng.uniform(-9, 9, 500), np.full(500, -3.0)])
    d = np.column_stack([rng.uniform(-0.1, 0.1, 500), rng.uniform(-0.1, 0.1, 500), np.ones(500)])
    r = trace(lens, o, d, clip=False)
    assert not r.vignetted.any()
    from lensmount.optics.profiles import Profile
    prof = Profile.of(lens.surfaces[0])
    p = r.points[0]
    np.testing.assert_allclose(p[:, 2], prof.sag(p[:, 0] ** 2 + p[:, 1] ** 2), atol=1e-11)
    # Snell with the numerically differentiated surface normal
    eps = 1e-6
    rr = np.hypot(p[:, 0], p[:, 1])
    dsdr = (prof.sag((rr + eps) ** 2) - prof.sag((rr - eps) ** 2)) / (2 * eps)
    nrm = np.column_stack([-dsdr * p[:, 0] / rr, -dsdr * p[:, 1] / rr, np.ones(len(p))])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    d_in = d / np.linalg.norm(d, axis=1, keepdims=True)
    n1, n2 = 1.0, float(refractive_index("N-BK7", lens.primary_wavelength_um))
    sin_in = np.linalg.norm(np.cross(d_in, nrm), axis=1)
    sin_out = np.linalg.norm(np.cross(r.directions[0], nrm), axis=1)
    np.testing.assert_allclose(n1 * sin_in, n2 * sin_out, atol=1e-8)


def test_random_lenses_and_rays_never_produce_nan():
    rng = np.random.default_rng(5)
    for _ in range(30):
        r1, r2 = rng.choice([-1, 1]) * rng.uniform(5, 100), rng.choice([-1, 1]) * rng.uniform(5, 100)
        lens = Prescription((Surface(r1, rng.uniform(0.5, 10), "N-SF6", conic=rng.uniform(-3, 1),
                                     clear_semi_diameter=rng.uniform(1, 20), is_stop=True),
                             Surface(r2, rng.uniform(-5, 50))), Aperture("epd", 5.0))
        n = 300
        o = np.column_stack([rng.normal(0, 15, n), rng.normal(0, 15, n), rng.uniform(-20, 0, n)])
        d = rng.normal(size=(n, 3))
        r = trace(lens, o, d, clip=bool(rng.integers(2)))
        assert np.all(np.isfinite(r.points)) and np.all(np.isfinite(r.directions))
        assert np.all((r.vignetted_at >= -1) & (r.vignetted_at <= 2))
        np.testing.assert_array_equal(r.vignetted, r.vignetted_at >= 0)


def test_a_ray_from_beyond_the_centre_of_a_concave_surface_meets_its_vertex_sheet():
    """An object (or a previous surface) farther in front of a surface concave toward it than its
    radius: the ray starts beyond the centre of curvature, where the first root of the quadratic is
    the far sheet. Against the textbook sphere intersection |o + t d − C|² = R², the root nearer
    the vertex plane, for origins in front of and beyond the centre (R = −50 mm, centre at z = −50)."""
    from lensmount.optics.profiles import Profile

    radius = -50.0
    profile = Profile(curvature=1.0 / radius, conic=0.0, aspheric=())
    rng = np.random.default_rng(4)
    n = 400
    o = np.column_stack([rng.uniform(-8, 8, (n, 2)), rng.uniform(-1000.0, -5.0, n)])
    tilt, az = np.radians(4.0) * rng.random(n), 2 * np.pi * rng.random(n)
    d = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    oc = o - [0.0, 0.0, radius]
    b = np.einsum("ij,ij->i", oc, d)
    disc = b * b - (np.einsum("ij,ij->i", oc, oc) - radius ** 2)
    meets = disc >= 0.0
    roots = -b[:, None] + np.array([-1.0, 1.0]) * np.sqrt(np.where(meets, disc, 0.0))[:, None]
    z = o[:, 2, None] + roots * d[:, 2, None]
    want = roots[np.arange(n), np.argmin(np.abs(z), axis=1)]  # the vertex sheet: the crossing near z = 0
    assert np.sum(meets & (o[:, 2] < radius)) > n // 4  # many start beyond the centre and meet the sphere
    got = profile.intersect(o, d)
    np.testing.assert_allclose(got[meets], want[meets], rtol=1e-12, atol=1e-9)
    assert np.all(np.isinf(got[~meets]))
    # Through the sequential trace: a singlet 1 m behind an object point, concave toward it.
    glass = dict(clear_semi_diameter=12.0, mechanical_semi_diameter=12.0)
    lens = Prescription((Surface(radius=radius, thickness=6.0, material="SCHOTT:N-BK7", **glass),
                         Surface(radius=-30.0, thickness=80.0, **glass)), Aperture("epd", 10.0))
    slope = np.radians(0.25) * rng.random(n)
    d = np.column_stack([np.sin(slope) * np.cos(az), np.sin(slope) * np.sin(az), np.cos(slope)])
    r = trace(lens, np.tile([0.0, 0.0, -1000.0], (n, 1)), d)
    assert not r.vignetted.any()
