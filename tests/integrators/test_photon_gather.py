"""Face-aware gather: thin-edge isolation and the Lambertian density estimate against L = ρE/π."""

import math

import numpy as np
import pytest

from lensmount.integrators.photon_mapping.photon_gather import Gatherer, HitPoints, PhotonHits


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


def test_glossy_rule_routes_by_the_share_of_the_lobe_a_gather_can_catch():
    """Lambertian and wide lobes: all gathered (core 0); a 5° Gaussian: photons only (inf);
    black-paint ABg with a 1.8° half width but 35 % of its albedo beyond 15°: gathered outside
    the core; a mirror: photons only. The share is the BSDF's own albedo split, checked against
    an independent quadrature of the ABg lobe at normal incidence."""
    import math

    from lensmount.integrators.bidirectional import gather_cores
    from lensmount.integrators.photon_mapping.photon_gather import gatherable_share
    from lensmount.physics.bsdf import make_bsdf

    abg = make_bsdf("abg", A=2e-3, B=1e-3, g=2)
    finishes = [make_bsdf("lambertian", reflectance=0.05), make_bsdf("gaussian", reflectance=0.05, half_width_deg=5.0),
                abg, make_bsdf("mirror", reflectance=0.9), None]
    core = gather_cores(finishes)
    cone = math.sin(math.radians(15.0))
    assert core[0] == 0.0 and core[1] == np.inf and core[2] == pytest.approx(cone) and core[3] == np.inf
    assert core[4] == np.inf
    # Normal incidence: f = A / (B + ρ²) in direction cosines, albedo = ∫ f cos θ dω = ∫ f d²β.
    rho = np.linspace(0.0, 1.0, 200_001)
    ring = 2 * np.pi * rho * 2e-3 / (1e-3 + rho**2)
    inner = np.trapezoid(np.where(rho < cone, ring, 0.0), rho)
    share0 = 1.0 - inner / np.trapezoid(ring, rho)
    g = 48
    u = (np.arange(g) + 0.5) / g
    uu = np.column_stack([np.repeat(u, g), np.tile(u, g)])
    n = np.tile([0.0, 0.0, 1.0], (len(uu), 1))
    wo, w, _ = abg.sample(n.copy(), n, uu)
    t = wo[:, :2]
    share_sampled = w[np.hypot(t[:, 0], t[:, 1]) >= cone].sum() / w.sum()
    assert share_sampled == pytest.approx(share0, abs=0.03)
    assert 0.25 < gatherable_share(abg, cone) < 0.6


def test_each_hit_point_gathers_the_photons_of_its_wavelength_within_each_rung_of_its_radius():
    """Radii spread over two octaves and two wavelengths, against every (hit point, photon) pair summed
    directly: a photon of the other wavelength, or beyond r · BIAS_LADDER[l], adds nothing to rung l
    (the pair test that runs before the normals, `_pairs_in_reach`)."""
    from lensmount.integrators.photon_mapping.photon_gather import BIAS_LADDER

    rng = np.random.default_rng(3)
    h, m = 300, 4000
    up = np.tile([0.0, 0.0, 1.0], (h, 1))
    hits = HitPoints(np.column_stack([rng.uniform(0, 10, (h, 2)), np.zeros(h)]), up, up, np.ones(h),
                     np.arange(h, dtype=np.int64), np.zeros(h, np.int32), rng.integers(0, 2, h).astype(np.int32),
                     rng.uniform(0.2, 0.8, h))
    flux = rng.uniform(0.5, 1.5, m)
    photons = PhotonHits(np.column_stack([rng.uniform(0, 10, (m, 2)), np.zeros(m)]), np.tile([0.0, 0.0, -1.0], (m, 1)),
                         np.tile([0.0, 0.0, 1.0], (m, 1)), flux, np.zeros(m, np.int32),
                         rng.integers(0, 2, m).astype(np.int32))
    g = Gatherer(hits, [Lambert(0.3)])
    g.gather(photons)
    d = np.linalg.norm(hits.position[:, None, :] - photons.position[None, :, :], axis=2)
    same = hits.wavelength[:, None] == photons.wavelength[None, :]
    for rung, scale in enumerate(BIAS_LADDER):
        inside = same & (d < scale * hits.radius[:, None])
        expected = inside @ flux * 0.3 / math.pi / (math.pi * (scale * hits.radius) ** 2)
        assert np.allclose(g.radiance_ladder[:, rung], expected, rtol=1e-12, atol=0.0)
    assert np.allclose(g.radiance, g.radiance_ladder[:, 0], rtol=1e-12, atol=0.0)
    assert (g.radiance > 0).sum() > 0.9 * h


def test_the_compiled_ladder_sums_are_the_five_bincounts_to_the_bit():
    """`_add_ladder` replaced one bincount per rung added into its column: every rung of every hit point must
    be that float, over two chunks of pairs (a hit point met many times in each, in no order), and a
    non-finite product (a zero area) must be reported, not summed away."""
    from lensmount.integrators.photon_mapping.photon_gather import BIAS_LADDER, _add_ladder

    rng = np.random.default_rng(11)
    h_n, rungs = 50, np.asarray(BIAS_LADDER)
    cos_rungs = np.cos(np.radians(np.minimum(30.0 * np.maximum(rungs, 1.0), 89.0)))
    area = rng.uniform(1e-3, 2.0, (h_n, len(rungs)))
    reference = rng.uniform(0, 1, (h_n, len(rungs)))
    ladder = reference.copy()
    sums, touched = np.zeros_like(ladder), np.zeros(h_n, bool)
    for _ in range(2):
        p = 4000
        hi = rng.integers(0, h_n, p)
        contrib = rng.lognormal(0.0, 3.0, p)
        distance = rng.uniform(0.0, 2.2, p)
        cos_n = rng.uniform(0.5, 1.0, p)
        within = ((distance[:, None] < rungs) & (cos_n[:, None] > cos_rungs)) / area[hi]
        for rung in range(len(rungs)):
            reference[:, rung] += np.bincount(hi, weights=contrib * within[:, rung], minlength=h_n)
        assert _add_ladder(hi, contrib, distance, cos_n, rungs, cos_rungs, area, ladder, sums, touched)
        assert np.array_equal(ladder, reference)
        assert not sums.any() and not touched.any()
    area[hi[0], 0] = 0.0
    assert not _add_ladder(hi, contrib, distance, cos_n, rungs, cos_rungs, area, ladder, sums, touched)
