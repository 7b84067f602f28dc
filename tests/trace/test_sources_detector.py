"""Sources (direction convention, solar disc, emission disc, flux per photon) and the detector."""

import math

import numpy as np
import pytest

from lensmount.physics.detector import Detector
from lensmount.physics.sampler import stream
from lensmount.physics.sources import CollimatedSource, SunSource, emission_disc, source_direction


def _sun(theta, phi=90.0, radius=30.0, limb=False, diameter=0.53):
    d = source_direction(theta, phi)
    disc = emission_disc(d, 0.0, radius, 500.0, 0.5 * math.radians(diameter))
    return SunSource(theta, phi, disc, diameter, limb)


def test_direction_convention():
    # Azimuth 90°: the source is displaced toward +y, so its light travels toward -y.
    d = source_direction(7.0, 90.0)
    assert d == pytest.approx([0.0, -math.sin(math.radians(7)), math.cos(math.radians(7))], abs=1e-15)
    assert source_direction(0.0, 33.0) == pytest.approx([0, 0, 1.0])
    assert source_direction(120.0, 0.0)[2] < 0  # behind the lens


@pytest.mark.parametrize("limb", [False, True])
def test_sun_directions_fill_the_053_degree_disc(limb):
    sun = _sun(7.0, limb=limb)
    rays, flux = sun.emit(200_000, stream(1, "test-sun", 0))
    ang = np.degrees(np.arccos(np.clip(rays.direction @ sun.direction, -1, 1)))
    assert ang.max() <= 0.265 + 1e-9
    # Uniform disc: P(angle < a) = (a / 0.265)²; mean angle = 2/3 of the radius.
    mean_fraction = ang.mean() / 0.265
    if limb:
        assert mean_fraction < 2 / 3 - 0.01  # limb darkening pulls light toward the centre
    else:
        assert mean_fraction == pytest.approx(2 / 3, abs=0.003)
    assert flux == pytest.approx(sun.disc.area / 200_000)
    np.testing.assert_allclose(rays.weight, flux)


def test_emission_disc_covers_the_front_opening_and_lies_outside():
    """Every ray of the source that crosses the opening (radius 30 at z = 0) starts on the disc:
    the disc's projection along each sun direction covers the opening."""
    for theta in (0.0, 7.0, 60.0, 89.0):
        sun = _sun(theta)
        rays, _ = sun.emit(100_000, stream(2, "cover", int(theta)))
        d = rays.direction
        t = -rays.origin[:, 2] / d[:, 2]
        p = rays.origin + t[:, None] * d
        r = np.hypot(p[:, 0], p[:, 1])
        # The hits on z = 0 fill the opening: points near the rim all around exist.
        near_rim = r > 29.0
        ang = np.arctan2(p[near_rim, 1], p[near_rim, 0])
        assert np.histogram(ang, bins=12, range=(-math.pi, math.pi))[0].min() > 0
        # Start at least clear_distance (500) away from the opening's centre.
        assert np.linalg.norm(rays.origin, axis=1).min() >= 500.0 - 1e-9


def test_collimated_source_is_parallel():
    d = source_direction(3.0, 45.0)
    src = CollimatedSource(3.0, 45.0, emission_disc(d, 0.0, 10.0, 100.0))
    rays, flux = src.emit(1000, stream(3, "c", 0))
    np.testing.assert_allclose(rays.direction, np.broadcast_to(d, (1000, 3)), atol=1e-15)
    assert flux * 1000 == pytest.approx(src.disc.area)


def test_same_seed_same_photons():
    sun = _sun(7.0)
    a, _ = sun.emit(1000, stream(5, "photons", 2))
    b, _ = sun.emit(1000, stream(5, "photons", 2))
    c, _ = sun.emit(1000, stream(5, "photons", 3))
    np.testing.assert_array_equal(a.origin, b.origin)
    assert not np.array_equal(a.origin, c.origin)


def test_detector_pixels_edges_and_deposit():
    det = Detector(4.0, 2.0, 4, 2, 100.0)
    pts = np.array([[-2.0, -1.0, 100], [1.999, 0.999, 100], [2.0, 1.0, 100], [2.01, 0, 100], [np.nan, 0, 100],
                    [-0.5, 0.5, 100]])
    assert list(det.pixel_of(pts)) == [0, 7, 7, -1, -1, 5]
    u = np.random.default_rng(0).random((8, 2))
    pix = np.arange(8)
    assert np.array_equal(det.pixel_of(det.sample_points(pix, u)), pix)
    img = det.deposit(pts, np.array([1.0, 2.0, 3.0, 4.0, 5.0, np.inf]))
    assert img.shape == (2, 4) and np.all(np.isfinite(img))
    assert img.sum() * det.pixel_area == pytest.approx(6.0)  # off-detector and non-finite flux dropped
    assert img[0, 0] == pytest.approx(1.0 / det.pixel_area)  # row 0 = -y edge, column 0 = -x edge


def test_detector_spectral_weight_and_single_pixel():
    det = Detector(1.0, 1.0, 1, 1, 5.0, spectral_weight=(1.0, 0.5))
    pts = np.zeros((2, 3))
    img = det.deposit(pts, np.array([1.0, 1.0]), np.array([0, 1]))
    assert img.shape == (1, 1) and img[0, 0] == pytest.approx(1.5)


def test_detector_hit_from_behind_is_flagged():
    det = Detector(10.0, 10.0, 2, 2, 50.0)
    o = np.array([[0, 0, 0.0], [0, 0, 100.0], [0, 0, 50.0]])
    d = np.array([[0, 0, 1.0], [0, 0, -1.0], [0, 0, 1.0]])
    t, front = det.intersect(o, d, 1e-9)
    assert t[0] == 50.0 and front[0]
    assert t[1] == 50.0 and not front[1]
    assert t[2] == np.inf  # starting on the detector: no self-hit


# ---------------------------------------------------------------- the sun at and beyond 90°

def test_directions_are_exact_at_right_angles():
    assert source_direction(90.0, 90.0)[2] == 0.0  # not cos(π/2) = 6e-17
    assert list(source_direction(180.0, 30.0)) == [0.0, 0.0, -1.0]
    assert list(source_direction(90.0, 0.0)) == [-1.0, 0.0, 0.0]


def test_entering_fraction_against_closed_forms():
    from lensmount.physics.sources import entering_fraction

    a = 0.5 * math.radians(0.53)
    for theta in (0.0, 30.0, 89.0):  # collimated: cos θ
        assert entering_fraction(theta) == pytest.approx(math.cos(math.radians(theta)), rel=1e-12)
    for theta in (90.0, 120.0, 180.0):
        assert entering_fraction(theta) == 0.0
    # Uniform solar disc: on axis, the mean of cos ρ is 1 − α²/4; at 90° the upper half-disc gives
    # the mean of max(sin ρ cos ψ, 0) = α · (2/3) · (1/π).
    assert entering_fraction(0.0, a) == pytest.approx(1.0 - a * a / 4, abs=1e-9)
    assert entering_fraction(90.0, a) == pytest.approx(2 * a / (3 * math.pi), rel=1e-3)
    assert entering_fraction(90.0 + math.degrees(a), a) == 0.0 and entering_fraction(120.0, a) == 0.0


@pytest.mark.parametrize("theta", [90.0, 120.0, 180.0])
def test_sun_behind_the_entrance_plane_says_why(theta):
    sun = _sun(theta)
    if theta == 90.0:  # half the disc is still above the plane: light enters, grazing
        assert sun.no_light_enters is None and sun.entering_fraction > 0
    else:
        assert sun.entering_fraction == 0.0
        assert "behind the entrance plane" in sun.no_light_enters and "no light enters" in sun.no_light_enters
    col = CollimatedSource(theta, 0.0, sun.disc)
    assert col.entering_fraction == 0.0 and "behind the entrance plane" in col.no_light_enters


@pytest.mark.parametrize("theta", [89.9, 90.0, 120.0, 180.0])
def test_emission_disc_covers_the_whole_assembly_when_light_comes_from_the_side_or_behind(theta):
    """Light from behind may still reach the detector through an open back: none of the assembly
    (here a sphere of radius `clear` around the opening) may lie outside the photons' beam."""
    clear, opening = 500.0, 30.0
    d = source_direction(theta, 40.0)
    disc = emission_disc(d, 0.0, opening, clear, 0.5 * math.radians(0.53))
    centre = np.asarray(disc.centre)
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(5000, 3))
    pts *= (clear * rng.random(5000) ** (1 / 3) / np.linalg.norm(pts, axis=1))[:, None]
    across = (pts - centre) - ((pts - centre) @ d)[:, None] * d
    assert np.linalg.norm(across, axis=1).max() <= disc.radius
