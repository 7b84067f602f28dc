"""Photons aimed at the diaphragm edge: the band's density is exact, guided emission carries the
sun's flux through any region of the plane unbiased, the pilot finds the edge and is deterministic.

References are analytic: the band's support area 2h·2π·a₀ (the harmonics integrate to zero), the
probability of each azimuth bin and half band, and the area of a region of the plane P, which
uniform sunlight of unit irradiance crosses with flux equal to that area.
"""

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import double_gauss_case  # noqa: E402

from lensmount.integrators.photon_mapping import photon_target as PT  # noqa: E402
from lensmount.integrators.bidirectional import gather_cores  # noqa: E402
from lensmount.physics.sources import SunSource, emission_disc, orthonormal_basis, source_direction  # noqa: E402
from lensmount.trace.tracer import FACE, Tracer  # noqa: E402

THETA = 7.0
D0 = source_direction(THETA, 90.0)
CENTRE = (0.0, 0.0, 20.0)


def _band(n_wl=2, half=0.05):
    """ρ* = 10 + 0.5 cos φ + 0.3 sin 2φ (+0.2 per wavelength), a lopsided azimuth pmf."""
    coef = np.zeros((n_wl, 2 * PT._K + 1))
    coef[:, 0] = 10.0 + 0.2 * np.arange(n_wl)
    coef[:, 1], coef[:, 4] = 0.5, 0.3
    pmf = 1.0 + np.arange(PT.N_PHI) % 7
    return PT.EdgeBand(CENTRE, tuple(D0), coef, np.full(n_wl, half), pmf / pmf.sum())


def _sun(n_wl=2):
    disc = emission_disc(D0, opening_z=0.0, opening_radius=15.0, clear_distance=300.0,
                         half_angle_rad=math.radians(0.265))
    return SimpleNamespace(source=SunSource(THETA, 90.0, disc, wavelength_weights=(1.0,) * n_wl))


def test_band_samples_have_the_density_it_reports():
    band, n = _band(), 400_000
    rng = np.random.default_rng(3)
    wl = rng.integers(0, 2, n)
    p = band.sample(rng.random((n, 2)), wl)
    e1, e2 = orthonormal_basis(D0)
    q = p - np.asarray(CENTRE)
    assert np.allclose(q @ D0, 0.0, atol=1e-9)  # on the plane P
    rho, phi = np.hypot(q @ e1, q @ e2), np.arctan2(q @ e2, q @ e1)
    dens = band.density(rho, phi, wl)
    assert np.all(dens > 0)
    # E[1/density] over the samples is the support's area, 2h · 2π a₀ per wavelength.
    for k in range(2):
        inv = 1.0 / dens[wl == k]
        want = 2 * 0.05 * 2 * math.pi * band.coef[k, 0]
        assert abs(inv.mean() - want) < 5 * inv.std() / math.sqrt(len(inv))
    # Each azimuth bin, and the inner half of the band in it, get their analytic share.
    b = np.clip(((phi + math.pi) * PT.N_PHI / (2 * math.pi)).astype(int), 0, PT.N_PHI - 1)
    inner = rho < band.radius(phi, wl)
    for cell, want in ((np.bincount(b, minlength=PT.N_PHI), band.pmf),
                       (np.bincount(b[inner], minlength=PT.N_PHI), 0.5 * band.pmf)):
        assert np.all(np.abs(cell / n - want) < 5 * np.sqrt(want / n))


@pytest.mark.parametrize("region", ["straddles the band", "beside it", "inside it", "in the wide band only"])
def test_guided_photons_carry_the_suns_flux_through_any_region(region):
    """Σ Φ of the photons crossing a region of P equals its area (unit irradiance), whether the region
    lies in the band, straddles its edge or lies where only the uniform share reaches."""
    scene, band, n = _sun(), _band(), 200_000
    rays = PT.guided_photons(scene, band, 7, "photons", 0, n)
    assert np.all(np.isfinite(rays.weight)) and rays.alive.all()
    rho, phi = band.crossing(rays.origin, rays.direction)
    lo, hi, sector = {"straddles the band": (-0.08, 0.02, (-1.0, 1.5)), "beside it": (0.5, 2.0, (-3.0, 3.0)),
                      "inside it": (-0.03, 0.03, (0.2, 2.9)), "in the wide band only": (0.1, 0.3, (-2.0, 2.0))}[region]
    # The region: ρ − ρ*(φ, λ=0) in [lo, hi] over an azimuth sector; area ∫ ((ρ*+hi)² − (ρ*+lo)²)/2 dφ.
    r0_ref = band.radius(phi, np.zeros(n, int))
    inside = (rho - r0_ref >= lo) & (rho - r0_ref < hi) & (phi >= sector[0]) & (phi < sector[1])
    f = np.linspace(*sector, 20001)
    rs = band.radius(f, np.zeros(len(f), int))
    area = np.trapezoid(0.5 * ((rs + hi) ** 2 - (rs + lo) ** 2), f)
    w = np.where(inside, rays.weight, 0.0)
    assert abs(w.sum() - area) < 5 * w.std() * math.sqrt(n) + 1e-9, (w.sum(), area)


def test_uniform_share_keeps_every_start_on_the_disc_reachable():
    scene, band, n = _sun(), _band(), 100_000
    rays = PT.guided_photons(scene, band, 7, "photons", 0, n)
    plain = PT.guided_photons(scene, None, 7, "photons", 0, n)
    # No band: exactly the source's emission, Φ = A_S / N.
    assert np.allclose(plain.weight, scene.source.disc.area / n)
    # With it: no photon heavier than the uniform share allows; in the band the narrow share, its part
    # of the wide one (1/WIDE_FACTOR) and the uniform photons' (nil); near it no photon heavier than
    # the wide share allows.
    assert rays.weight.max() <= scene.source.disc.area / (PT.UNIFORM_SHARE * n) * (1 + 1e-12)
    rho, phi = band.crossing(rays.origin, rays.direction)
    in_band = band.density(rho, phi, rays.wavelength) > 0
    want = 1 - PT.UNIFORM_SHARE - PT.WIDE_SHARE + PT.WIDE_SHARE / PT.WIDE_FACTOR
    assert abs(in_band.mean() - want) < 0.01
    wide = band.widened(PT.WIDE_FACTOR)
    near = wide.density(rho, phi, rays.wavelength) > 0
    assert rays.weight[near].max() <= 1 / (n * PT.WIDE_SHARE * wide.density(rho, phi, rays.wavelength)[near].min())


@pytest.fixture(scope="module")
def case1():
    scene = double_gauss_case(1, pixels=(16, 16))
    return scene, Tracer(scene)


@pytest.mark.slow  # two pilots of 2 × 10⁵ photons through the synthetic double Gauss: ~20 s
def test_pilot_finds_the_edge_and_is_deterministic(case1):
    scene, tracer = case1
    broad = np.isfinite(gather_cores(scene.bsdf_of_tag))
    band = PT.edge_band(scene, tracer, broad, 5)
    assert band is not None
    again = PT._pilot(scene, tracer, broad, 5, PT.PILOT_PHOTONS)
    assert np.array_equal(band.coef, again.coef) and np.array_equal(band.pmf, again.pmf)
    n = 40_000
    tags = PT.edge_tags(scene, broad)
    hits = {}
    for name, b in (("band", band), ("uniform", None)):
        rays = PT.guided_photons(scene, b, 11, "photons", 0, n)
        ev = tracer.next_event(rays, np.random.default_rng(0))
        hits[name] = np.count_nonzero((ev.kind == FACE) & np.isin(ev.tag, tags))
    assert hits["band"] > 50 * max(hits["uniform"], 1)


def test_no_band_when_other_faces_scatter():
    scene = double_gauss_case(2, pixels=(4, 4))
    broad = np.isfinite(gather_cores(scene.bsdf_of_tag))
    assert PT.edge_band(scene, Tracer(scene), broad, 5, n_photons=1000) is None


def test_a_dimly_lit_edge_is_found_with_more_pilot_rounds(case1):
    """With a quarter of the pilot's photons a round, the first round meets the edge too rarely to
    fit the ring; more rounds of the same size find it, and the band it gives aims photons at the
    edge (a single round gave no band: uniform emission, ~100× fewer photons on the edge)."""
    scene, tracer = case1
    broad = np.isfinite(gather_cores(scene.bsdf_of_tag))
    n = PT.PILOT_PHOTONS // 4
    tags = PT.edge_tags(scene, broad)
    first = PT.first_band(scene, tags)
    one_round = PT._pilot_photons(scene, tracer, first, tags, 5, "photon-pilot", 0, np.arange(n))[1].sum()
    assert 0 < one_round < PT.MIN_HITS
    rays, hit = PT._stage_one(scene, tracer, first, tags, 5, n)
    assert len(rays) > n and hit.sum() >= PT.MIN_HITS  # it went on past the first round until it had enough
    assert hit[:-n].sum() < PT.MIN_HITS  # and stopped there
    band = PT.edge_band(scene, tracer, broad, 5, n_photons=n)
    assert band is not None
    m = 20_000
    got = {}
    for name, b in (("band", band), ("uniform", None)):
        ev = tracer.next_event(PT.guided_photons(scene, b, 11, "photons", 0, m), np.random.default_rng(0))
        got[name] = np.count_nonzero((ev.kind == FACE) & np.isin(ev.tag, tags))
    assert got["band"] > 20 * max(got["uniform"], 1), got


def test_band_photons_started_beside_the_source_disc_carry_nothing():
    """The bands' photons are moved back to the disc's plane; where that lands beside the
    disc there is no sunlight. A band straddling the disc's rim: Σ Φ through the region of P whose
    starts lie on the disc is its area, and every photon started off the disc has Φ = 0."""
    scene, n = _sun(), 200_000
    disc = scene.source.disc
    coef = np.zeros((2, 2 * PT._K + 1))
    coef[:, 0] = disc.radius  # the ring on P lies over the disc's rim (P is normal to d₀ like the disc)
    band = PT.EdgeBand(tuple(np.asarray(disc.centre) + 30.0 * D0), tuple(D0), coef, np.full(2, 0.5),
                       np.full(PT.N_PHI, 1.0 / PT.N_PHI))
    rays = PT.guided_photons(scene, band, 7, "photons", 0, n)
    c, d0 = np.asarray(disc.centre), np.asarray(D0)
    rel = rays.origin - c
    off = np.linalg.norm(rel - (rel @ d0)[:, None] * d0, axis=1) > disc.radius
    assert 0.01 < off.mean() and np.all(rays.weight[off] == 0.0) and not rays.alive[off].any()
    # Within 0.2 mm of the rim on P (starts on the disc: the sun's directions are within 0.27° of d₀
    # over 30 mm, 0.14 mm at most): Σ Φ is that annulus's area inside the disc.
    rho, _ = band.crossing(rays.origin, rays.direction)
    ring = (rho > disc.radius - 0.4) & (rho < disc.radius - 0.2)
    area = math.pi * ((disc.radius - 0.2) ** 2 - (disc.radius - 0.4) ** 2)
    w = np.where(ring, rays.weight, 0.0)
    assert abs(w.sum() - area) < 5 * w.std() * math.sqrt(n)


def _pilot_rays(rings, n=200_000, seed=4):
    """Pilot photons along d₀ crossing P uniformly over the annulus 9…13 mm, and which met the edge:
    those within ±0.02 mm of one of `rings` ((φ → ρ, share of the photons there that meet it))."""
    rng = np.random.default_rng(seed)
    e1, e2 = orthonormal_basis(D0)
    rho, phi = rng.uniform(9.0, 13.0, n), rng.uniform(-math.pi, math.pi, n)
    p = np.asarray(CENTRE) + (rho * np.cos(phi))[:, None] * e1 + (rho * np.sin(phi))[:, None] * e2
    rays = PT.RayBatch.make(p - 50.0 * D0, np.tile(D0, (n, 1)), wavelength=np.zeros(n, np.int64),
                            ids=np.arange(n))
    hit = np.zeros(n, bool)
    for ring, rate in rings:
        hit |= (np.abs(rho - ring(phi)) <= 0.02) & (rng.random(n) < rate)
    return rays, hit


def test_an_edge_lit_through_two_rings_gets_both():
    """Hits on a second, dimmer ring are not dropped as a single-valued fit's outliers: the pilot's
    fit keeps a ring for each, shares by their hits, and a density that is the
    mixture's. (Two rings about equally lit are not separated: the first fit runs between them.)"""
    first, second = (lambda f: 10.0 + 0.3 * np.cos(f)), (lambda f: 12.0 + 0.1 * np.sin(2 * f))
    rays, hit = _pilot_rays([(first, 1.0), (second, 0.04)])
    fit = PT._fit(rays, hit, CENTRE, D0, 1, per_wavelength=True)
    assert isinstance(fit, PT.EdgeRings) and len(fit.rings) == 2
    f = np.linspace(-3, 3, 7)
    got = sorted((r.radius(f, np.zeros(7, int)) for r in fit.rings), key=lambda x: x[0])
    assert np.allclose(got[0], first(f), atol=0.005) and np.allclose(got[1], second(f), atol=0.015)  # ~80 hits
    assert fit.share[1] == pytest.approx(0.48 / 10.48, abs=0.02)  # hits ∝ length × rate: 10 : 12 · 0.04
    # its samples have the density it reports: E[1/q] over them is the two bands' area
    u = np.random.default_rng(5).random((200_000, 3))
    p = fit.sample(u[:, 1:], np.zeros(len(u), int), u[:, 0])
    rho, phi = fit.crossing(p - D0, np.tile(D0, (len(u), 1)))
    inv = 1.0 / fit.density(rho, phi, np.zeros(len(u), int))
    want = sum(2 * r.half_width[0] * 2 * math.pi * r.coef[0, 0] for r in fit.rings)
    assert abs(inv.mean() - want) < 5 * inv.std() / math.sqrt(len(inv))


def test_one_ring_stays_one_band():
    """A single lit ring (its own residual tails beyond 4σ included) gives the EdgeBand, as before."""
    rays, hit = _pilot_rays([(lambda f: 10.0 + 0.3 * np.cos(f), 1.0)])
    rng = np.random.default_rng(6)
    hit |= rng.random(len(hit)) < 5e-5  # a few stray hits anywhere: scattered, not a ring
    assert isinstance(PT._fit(rays, hit, CENTRE, D0, 1, per_wavelength=True), PT.EdgeBand)


def test_the_check_adds_a_ring_the_fit_left_out():
    """A fit holding only the first of two lit rings (the second carries ~26 % of the edge's light)
    is mended by the check's hits: a ring on the second, shares by the light each holds, the density the
    mixture's. (The check's photons here cross P uniformly in ρ: each carries light ∝ ρ.)"""
    first, second = (lambda f: 10.0 + 0.3 * np.cos(f)), (lambda f: 12.0 + 0.1 * np.sin(2 * f))
    rays, hit = _pilot_rays([(first, 1.0), (second, 0.3)], n=100_000, seed=8)
    coef = np.zeros((1, 2 * PT._K + 1))
    coef[0, 0], coef[0, 1] = 10.0, 0.3
    fit = PT.EdgeBand(CENTRE, tuple(D0), coef, np.array([0.03]), np.full(PT.N_PHI, 1.0 / PT.N_PHI))
    rho, _ = fit.crossing(rays.origin, rays.direction)
    light = np.where(hit, rho, 0.0)
    mended, added = PT._mended(fit, rays, hit, light)
    assert added == 1 and isinstance(mended, PT.EdgeRings) and mended.rings[0] is fit
    f = np.linspace(-3, 3, 7)
    assert np.allclose(mended.rings[1].radius(f, np.zeros(7, int)), second(f), atol=0.01)
    want = 0.3 * 12.0 / (10.0 + 0.3 * 12.0)  # hits ∝ rate (uniform in ρ and φ), each carrying ∝ ρ: 0.265
    assert mended.share[1] == pytest.approx(want, abs=0.03)
