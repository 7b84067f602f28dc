"""Face-aware gather: thin-edge isolation and the Lambertian density estimate against L = ρE/π."""

import math

import numpy as np
import pytest

from lensmount.integrators.photon_gather import Gatherer, HitPoints, PhotonHits


class Lambert:
    def __init__(self, rho):
        self.rho = rho

    def eval(self, wi, wo, n):
        cos_i = np.einsum("ij,ij->i", wi, n)
        cos_o = np.einsum("ij,ij->i", wo, n)
        return np.where((cos_i > 0) & (cos_o > 0), self.rho / math.pi, 0.0)


def _hits(pos, normal, tag, radius, omega_o=None):
    h = len(pos)
    return HitPoints(np.asarray(pos, float), np.asarray(normal, float),
                     np.asarray(omega_o if omega_o is not None else normal, float), np.ones(h),
                     np.arange(h, dtype=np.int64), np.asarray(tag, np.int32), np.zeros(h, np.int32),
                     np.asarray(radius, float))


def _photons(pos, direction, normal, flux, tag):
    m = len(pos)
    return PhotonHits(np.asarray(pos, float), np.broadcast_to(direction, (m, 3)).copy(),
                      np.broadcast_to(normal, (m, 3)).copy(), np.full(m, flux), np.full(m, tag, np.int32),
                      np.zeros(m, np.int32))


def test_plate_photons_10um_from_an_edge_hit_point_contribute_nothing():
    # Hit point in the middle of a 50 µm edge (tag 0, normal +x); plate face (tag 1, normal +z) beside it.
    hits = _hits([[0.0, 0.0, 0.0]], [[1.0, 0, 0]], [0], [0.04])
    plate = _photons([[0.0, 0.0, 0.010], [0.0, 0.005, 0.010]], [0, 0, -1.0], [0, 0, 1.0], 1.0, 1)
    g = Gatherer(hits, [Lambert(0.1), Lambert(0.1)])
    g.gather(plate)
    assert g.radiance[0] == 0.0
    # Same positions but tagged as the edge with the edge's normal: they count.
    edge = _photons([[0.0, 0.0, 0.010], [0.0, 0.005, 0.010]], [-1.0, 0, 0], [1.0, 0, 0], 1.0, 0)
    g.gather(edge)
    assert g.radiance[0] > 0


def test_photons_on_the_back_of_a_sheet_are_not_gathered():
    hits = _hits([[0.0, 0.0, 0.0]], [[0, 0, 1.0]], [0], [1.0])
    back = _photons([[0.1, 0.0, 0.0]], [0, 0, 1.0], [0, 0, -1.0], 1.0, 0)
    g = Gatherer(hits, [Lambert(1.0)])
    g.gather(back)
    assert g.radiance[0] == 0.0


def test_lambertian_density_estimate_gives_rho_E_over_pi():
    """Uniform photons of irradiance E on a plane: L_o = ρ E / π whatever the radius."""
    rng = np.random.default_rng(2)
    side, m, rho = 20.0, 400_000, 0.3
    pos = np.column_stack([rng.uniform(-side / 2, side / 2, (m, 2)), np.zeros(m)])
    flux = 1.0 / m * side**2  # E = 1 (E_sun units)
    theta = math.radians(30)
    photons = _photons(pos, [math.sin(theta), 0, -math.cos(theta)], [0, 0, 1.0], flux, 0)
    radii = np.array([0.2, 0.5, 1.0, 2.0])
    hp = np.column_stack([rng.uniform(-3, 3, (4, 2)), np.zeros(4)])
    hits = _hits(hp, np.tile([0, 0, 1.0], (4, 1)), [0] * 4, radii,
                 omega_o=np.tile([0, math.sin(0.2), math.cos(0.2)], (4, 1)))
    g = Gatherer(hits, [Lambert(rho)])
    g.gather(photons)
    expected = rho * 1.0 / math.pi  # flux per area is E (photons on the surface, not cos-projected)
    counts = np.pi * radii**2 * m / side**2
    for L, n in zip(g.radiance, counts):
        assert L == pytest.approx(expected, rel=5 / math.sqrt(n))


def test_no_hit_points_and_no_photons_are_harmless():
    g = Gatherer(HitPoints.empty(), [Lambert(0.1)])
    g.gather(_photons(np.zeros((3, 3)), [0, 0, -1.0], [0, 0, 1.0], 1.0, 0))
    img, parts = g.image((2, 2), np.array([0]), 1)
    assert img.shape == (2, 2) and not img.any() and parts.shape == (1, 2, 2)


def test_chunked_gather_equals_one_chunk():
    rng = np.random.default_rng(8)
    m = 5000
    pos = np.column_stack([rng.uniform(-5, 5, (m, 2)), np.zeros(m)])
    photons = _photons(pos, [0, 0, -1.0], [0, 0, 1.0], 0.01, 0)
    hits = _hits(np.column_stack([rng.uniform(-4, 4, (50, 2)), np.zeros(50)]), np.tile([0, 0, 1.0], (50, 1)),
                 [0] * 50, rng.uniform(0.1, 1.0, 50))
    whole, parts = Gatherer(hits, [Lambert(0.5)]), Gatherer(hits, [Lambert(0.5)], chunk=333)
    whole.gather(photons)
    parts.gather(photons)
    np.testing.assert_allclose(parts.radiance, whole.radiance, rtol=1e-12)
    assert whole.radiance.sum() > 0
