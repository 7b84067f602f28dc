"""A learned photon target for the thin diaphragm edge: where sunlight must enter to meet it.

Why. On the paper's case 1 only the 50 µm diaphragm edge scatters. Sunlight meets it only
through a ring a few µm wide in the entrance pupil (the stop rim seen from object space), so
of the 10⁶ photons a pass spreads uniformly over the emission disc ~50 reach the edge: the
pass's value is a count of ~50 rare events (±14 %), whatever the view map does.

What. A deterministic *pilot* (its own stream, `stream(seed, "photon-pilot", 0)`, once per
(scene, tracer, seed) in each process, never from a pass) sends photons at the paraxial
entrance pupil's rim and records where the ones that met the edge crossed the plane P normal
to the sun's central direction d₀. A least-squares fit per wavelength gives the ring's radius

    ρ*(φ, λ) = Σ_k a_kλ cos kφ + b_kλ sin kφ,   k ≤ 4   (polar coordinates on P)

and its half width h_λ = `HALF_WIDTH_SIGMAS` × the residual spread; the plane's place along
d₀ is fitted too (the one where the sun's 0.53° spread of directions blurs the ring least,
near the entrance pupil), and a histogram of the hit rate over φ says which azimuths lead to
the edge. A second stage samples from the first fit to refine it. The first stage takes more
rounds of photons while fewer than MIN_HITS met the edge (a sun nearer the axis lights it through
a narrower ring: at 3° a round finds a third of what it finds at 7°), so a dim edge is still
found; the plan says when none was (`plan.Plan.as_dict`). Last, a check (`_checked`, after the
fit whatever made it) draws photons the fit never saw over stage 1's wide annulus and mends a
fit that misses the lit edge with rings fitted to what it missed (`PilotCheck`, in the plan).

Emission (`guided_photons`) is a mixture: with probability `UNIFORM_SHARE` a photon keeps the
source's uniform position on its disc; with `WIDE_SHARE` its crossing of P is drawn in a band
`WIDE_FACTOR` times as wide, every azimuth alike; otherwise in the band (φ from the histogram,
ρ uniform in ρ* ± h). Its start is moved back along its own direction to the disc's plane.
Directions and wavelengths are the source's. Every photon carries Φ = 1 / (N q) with the
mixture density q = c_u/A_S · [on the disc] + c_w p_wide + c_n p_band evaluated at its own
position, so the estimate stays unbiased whatever the fit's quality (uniform emission is
Φ = A_S / N); the uniform share keeps every path of light reachable and bounds Φ at A_S / (c_u N).
A photon of a band that starts off the source's disc carries nothing (the source has no light there).
Why the wide band: a photon that meets the edge just outside the band (~1 % of the edge's light
on the reference design, where the ring is a little wider at some azimuths than the fit's
mean spread) would otherwise be a uniform one carrying ~8 000 times a band photon's Φ; one such
photon made a pass read 5 times the others (a 39 % error over 8 passes). In the wide band it
carries ~40 times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.integrators.estimate import (
    EDGE_FLUX, EDGE_FLUX_SQ, PILOT_MISSED, PILOT_MISSED_AFTER, PILOT_RINGS_ADDED, scattering_tags)
from lensmount.integrators.photon_mapping.targets import N_DPHI as N_PHI
from lensmount.integrators.photon_mapping.targets import (
    azimuth_bin, azimuth_pmf, cached_pilot, edge_rim, edge_tags, paraxial_trace, robust_fit)
from lensmount.integrators.walk import emit_photons
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import Streams, stream
from lensmount.physics.sources import orthonormal_basis
from lensmount.trace.tracer import FACE

UNIFORM_SHARE = 0.2  # photons emitted uniformly on the disc (every path stays reachable)
WIDE_SHARE = 0.2  # photons in a band WIDE_FACTOR times as wide, every azimuth alike (near misses of the fit)
WIDE_FACTOR = 8.0
HALF_WIDTH_SIGMAS = 3.0  # band half width in residual standard deviations
PILOT_PHOTONS = 100_000  # per pilot stage (stage 1: per round)
PILOT_ROUNDS = 8  # stage 1's rounds at most, while fewer than MIN_HITS met the edge
DARK_ROUNDS = 4  # rounds without a single hit after which the edge counts as unlit
MIN_HITS = 40  # per wavelength, to fit the 9 coefficients; fewer: no learned target
MAX_RINGS = 3  # rings through which the pilot may find the edge lit
RING_SIGMAS = 4.0  # hits beyond this many residual spreads of a ring belong to another (as `targets.robust_fit`)
RING_SPREAD = 2.0  # a further ring's spread at most this many times the first's: hits on a ring, not the first ring's tails
# The check (`_checked`): a share of the edge's light found outside the fitted ring(s) above this is a miss, mended.
# Good fits leave 0-8.4 % there on case 1 (100 seeds, median 1 %: near misses, counted in the check's ~40 hits
# of 2.5 % each), a ring 12 half widths off 96-100 % (docs/accuracy.md, "A displaced learned ring").
CHECK_MISSED = 0.1
_K = 4  # harmonics of φ
_PLANE_SHIFTS = np.linspace(-40.0, 40.0, 21)  # mm along d₀ from the paraxial entrance pupil, tried by the fit
_SCAN_HITS = 2000  # hits (every m-th) the plane's place is fitted from

UNIFORM, WIDE, AIMED = 0, 1, 2  # `emission_component`
COMPONENTS = ("uniform", "wide", "aimed")
_CACHE: dict[tuple, tuple] = {}


def _basis(phi: np.ndarray) -> np.ndarray:
    """(N, 2K+1) columns 1, cos kφ, sin kφ."""
    cols = [np.ones_like(phi)]
    for k in range(1, _K + 1):
        cols += [np.cos(k * phi), np.sin(k * phi)]
    return np.stack(cols, axis=1)


@dataclass(frozen=True)
class EdgeBand:
    """The band on the plane P (through `centre`, normal to the sun's central direction `d0`, axes
    e1, e2 = `orthonormal_basis(d0)`) where photons meet the edge, per wavelength.

    coef : (W, 2K+1) fit of ρ*(φ); half_width : (W,) mm; pmf : (N_PHI,) azimuth probabilities."""

    centre: tuple[float, float, float]
    d0: tuple[float, float, float]
    coef: np.ndarray
    half_width: np.ndarray
    pmf: np.ndarray

    def crossing(self, origin: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ρ, φ) (N,) where rays (origin, direction) cross P, in P's polar coordinates."""
        return _crossing(self.centre, self.d0, origin, direction)

    def _wl(self, wavelength) -> np.ndarray:
        return np.clip(np.asarray(wavelength, np.int64), 0, len(self.coef) - 1)

    def widened(self, factor: float) -> "EdgeBand":
        """The same ring, `factor` times as wide, every azimuth equally likely."""
        return EdgeBand(self.centre, self.d0, self.coef, factor * self.half_width, np.full(N_PHI, 1.0 / N_PHI))

    def radius(self, phi: np.ndarray, wavelength) -> np.ndarray:
        """(N,) ρ*(φ, λ) in mm."""
        return np.einsum("nk,nk->n", _basis(phi), self.coef[self._wl(wavelength)])

    def density(self, rho: np.ndarray, phi: np.ndarray, wavelength) -> np.ndarray:
        """(N,) density per unit area of P at (ρ, φ): p(φ) / (2 h ρ) inside the band, else 0."""
        h = self.half_width[self._wl(wavelength)]
        b = azimuth_bin(phi)
        inside = (np.abs(rho - self.radius(phi, wavelength)) <= h) & (rho > 0)
        return np.where(inside, self.pmf[b] * (N_PHI / (2 * math.pi)) / (2.0 * h * np.where(rho > 0, rho, 1.0)), 0.0)

    def sample(self, u: np.ndarray, wavelength, pick: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) points of P for uniforms u (N, 2): φ from the histogram, ρ uniform in ρ* ± h; the
        density of the points is `density` wherever ρ > 0. `pick` chooses a ring (`EdgeRings`): one here."""
        cdf = np.cumsum(self.pmf)
        cdf[-1] = 1.0
        b = np.minimum(np.searchsorted(cdf, u[:, 1], side="right"), N_PHI - 1)
        lo = np.where(b > 0, cdf[np.maximum(b - 1, 0)], 0.0)
        frac = np.clip((u[:, 1] - lo) / self.pmf[b], 0.0, 1.0 - 1e-12)
        phi = -math.pi + (b + frac) * (2 * math.pi / N_PHI)
        rho = self.radius(phi, wavelength) + self.half_width[self._wl(wavelength)] * (2.0 * u[:, 0] - 1.0)
        rho = np.maximum(rho, 0.0)  # a band reaching the centre: the centre is one point of no density
        e1, e2 = orthonormal_basis(np.asarray(self.d0))
        return np.asarray(self.centre) + (rho * np.cos(phi))[:, None] * e1 + (rho * np.sin(phi))[:, None] * e2


@dataclass(frozen=True)
class EdgeRings:
    """Several rings on the same plane P through which the edge is lit (`_more_rings`), one EdgeBand
    each; a band photon takes ring r with probability `share[r]` (its share of the pilot's hits), and
    its density is the mixture Σ share_r · density_r, so any overlap of the rings is counted exactly."""

    rings: tuple[EdgeBand, ...]
    share: tuple[float, ...]

    @property
    def centre(self):
        return self.rings[0].centre

    @property
    def d0(self):
        return self.rings[0].d0

    def crossing(self, origin: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.rings[0].crossing(origin, direction)

    def widened(self, factor: float) -> "EdgeRings":
        return EdgeRings(tuple(r.widened(factor) for r in self.rings), self.share)

    def density(self, rho: np.ndarray, phi: np.ndarray, wavelength) -> np.ndarray:
        return sum(w * r.density(rho, phi, wavelength) for r, w in zip(self.rings, self.share))

    def sample(self, u: np.ndarray, wavelength, pick: np.ndarray | None = None) -> np.ndarray:
        """As `EdgeBand.sample`, the ring chosen by the uniforms `pick` (N,) against the shares."""
        which = np.minimum(np.searchsorted(np.cumsum(self.share), pick, side="right"), len(self.rings) - 1)
        out = np.zeros((len(u), 3))
        wl = np.broadcast_to(np.asarray(wavelength), (len(u),))
        for k, ring in enumerate(self.rings):
            rows = which == k
            out[rows] = ring.sample(u[rows], wl[rows])
        return out


def guided_photons(scene, band: EdgeBand | EdgeRings | None, seed: int, purpose: str, first: int, n: int) -> RayBatch:
    """Photons first … first+n−1 of the run (`walk.emit_photons`), a share 1 − UNIFORM_SHARE of them
    started so that they cross P in the band; each carries 1 / (n q) (module docstring)."""
    rays = emit_photons(scene, seed, purpose, first, n, n)
    if band is None:
        return rays
    disc = scene.source.disc
    wide = band.widened(WIDE_FACTOR)
    u = Streams(seed, purpose + "/emit-band", rays.id).random((n, 3))
    centre, d0 = np.asarray(disc.centre), np.asarray(band.d0)
    which = emission_component(seed, purpose, rays.id)
    # a photon's ring (several: `EdgeRings`): its component's uniform u₀, rescaled within the component's
    # interval, is uniform and independent of the two that place it in the ring
    for component, rows, lo, width in ((wide, which == WIDE, UNIFORM_SHARE, WIDE_SHARE),
                                       (band, which == AIMED, UNIFORM_SHARE + WIDE_SHARE,
                                        1.0 - UNIFORM_SHARE - WIDE_SHARE)):
        d = rays.direction[rows]
        pick = (u[rows, 0] - lo) / width
        rays.origin[rows] = _back_to_disc(component.sample(u[rows, 1:], rays.wavelength[rows], pick), d, centre, d0)
    on_disc = np.linalg.norm(rays.origin - centre - ((rays.origin - centre) @ d0)[:, None] * d0, axis=1) <= disc.radius
    rho, phi = band.crossing(rays.origin, rays.direction)
    q = (UNIFORM_SHARE * on_disc / disc.area + WIDE_SHARE * wide.density(rho, phi, rays.wavelength)
         + (1.0 - UNIFORM_SHARE - WIDE_SHARE) * band.density(rho, phi, rays.wavelength))
    # The source emits only from its disc: a band photon started beside it (~0.3 % on case 1) is light
    # that does not exist, so it carries nothing; q stays the density of where photons were drawn.
    rays.alive &= (q > 0) & on_disc
    rays.weight = np.where(rays.alive, 1.0 / (n * np.where(q > 0, q, 1.0)), 0.0)
    return rays


def emission_component(seed: int, purpose: str, ids: np.ndarray) -> np.ndarray:
    """(N,) which part of the mixture photons `ids` were drawn from: UNIFORM, WIDE or AIMED (the same
    numbers `guided_photons` draws, so the edge flux can be told by component after the walk)."""
    u0 = Streams(seed, purpose + "/emit-band", np.asarray(ids, np.int64)).random((len(ids), 3))[:, 0]
    return np.where(u0 < UNIFORM_SHARE, UNIFORM, np.where(u0 < UNIFORM_SHARE + WIDE_SHARE, WIDE, AIMED))


@dataclass(frozen=True)
class PilotCheck:
    """What the pilot's check (`_checked`) found: over independent photons drawn in the wide annulus
    of `first_band`, the share of the edge's light that met it outside the fitted ring(s) (`missed`),
    the rings fitted to those hits and added (`rings_added`), the share outside the mixture's aimed
    rings after that (`missed_after`, on the same photons) and how many check photons met the edge."""

    missed: float
    rings_added: int
    missed_after: float
    hits: int


def tally_edge_flux(diagnostics: dict, component: np.ndarray, flux: np.ndarray) -> None:
    """Add Σ Φ and Σ Φ² of photons' first arrivals at the edge, per emission component (`emission_component`),
    to a pass's diagnostics: how much of the edge's light each part of the mixture carries, and in how few
    photons (`plan.edge_flux_components` reads them)."""
    for k, name in enumerate(COMPONENTS):
        f = flux[component == k]
        diagnostics[EDGE_FLUX + name] = diagnostics.get(EDGE_FLUX + name, 0.0) + float(f.sum())
        diagnostics[EDGE_FLUX_SQ + name] = diagnostics.get(EDGE_FLUX_SQ + name, 0.0) + float(f @ f)


def edge_band(scene, tracer, broad: np.ndarray, seed: int,
              n_photons: int = PILOT_PHOTONS) -> EdgeBand | EdgeRings | None:
    """The pilot's EdgeBand (EdgeRings) for (scene, tracer, seed), checked (`_checked`), or None: no
    diaphragm edge, another face that scatters too (case 2: aiming photons at the edge would starve the
    faces that carry most of the light), a source other than the sun or a collimated one, too few pilot
    hits. Cached per process; a pure function of its arguments, so every pass and worker gets the same."""
    return _checked_pilot(scene, tracer, broad, seed, n_photons)[0]


def pilot_check(scene, tracer, broad: np.ndarray, seed: int, n_photons: int = PILOT_PHOTONS) -> PilotCheck | None:
    """The check of `edge_band`'s pilot (the same cached run), None when there is no band or the check's
    photons met the edge too rarely to say anything."""
    return _checked_pilot(scene, tracer, broad, seed, n_photons)[1]


def pilot_check_diagnostics(check: PilotCheck | None) -> dict[str, float]:
    """A pass's diagnostics from the pilot's check (`estimate.PILOT_MISSED`, …; none without a check)."""
    if check is None:
        return {}
    return {PILOT_MISSED: check.missed, PILOT_RINGS_ADDED: float(check.rings_added),
            PILOT_MISSED_AFTER: check.missed_after}


def _checked_pilot(scene, tracer, broad, seed, n_photons):
    key = (id(scene), id(scene.mesh), id(tracer), int(seed), int(n_photons))
    return cached_pilot(_CACHE, key, scene, tracer, lambda: _checked(
        scene, tracer, broad, int(seed), int(n_photons), _pilot(scene, tracer, broad, int(seed), int(n_photons))))


def _checked(scene, tracer, broad, seed, n_photons, fit):
    """(band, PilotCheck): the fit checked against photons it did not learn from, and mended where it
    misses the lit edge.

    Why. A ring fitted in the wrong place (a second ring the fit dropped, a fit misled, or a ring
    displaced on purpose by 12 half widths) leaves the edge's light to the
    uniform and wide photons, a few heavy ones per pass: the mean stays right but passes spread 2×,
    8-pass runs read 0 to 4× the truth and ±2 se holds it in 63-70 % of runs. So the check runs
    after the fit, whatever made it: rounds of `n_photons` from the stream "photon-pilot/check" drawn
    in the wide annulus of `first_band` (where stage 1 searched), each hit weighted by the flux its
    photon carries there (1 / the annulus's density). Where more than CHECK_MISSED of that light met
    the edge outside the fit's aimed rings, a ring is fitted to those hits (as `_more_rings`, up to
    MAX_RINGS, any spread: a wide ring over scattered hits still beats the uniform share), the rings'
    shares become their shares of the check's light, and a ring that carried none of it is dropped.
    Rounds go on until MIN_HITS met the edge and, on a miss, MIN_HITS met it outside (at most
    PILOT_ROUNDS). Each pass uses the one mixture this returns: the estimate stays unbiased."""
    if fit is None:
        return None, None
    tags = edge_tags(scene, broad)
    wide = first_band(scene, tags)
    batches, hits = [], []
    for r in range(PILOT_ROUNDS):
        rays, hit = _pilot_photons(scene, tracer, wide, tags, seed, "photon-pilot/check", r,
                                   np.arange(r * n_photons, (r + 1) * n_photons, dtype=np.int64))
        batches.append(rays)
        hits.append(hit)
        rays, hit = RayBatch.concatenate(batches), np.concatenate(hits)
        light, outside = _check_light(wide, fit, rays, hit)
        found, missed = int(hit.sum()), _share(light, outside)
        if found >= MIN_HITS and (missed <= CHECK_MISSED or np.count_nonzero(outside) >= MIN_HITS):
            break
        if found == 0 and r + 1 >= DARK_ROUNDS:
            break
    if found < MIN_HITS:
        return fit, None
    if missed <= CHECK_MISSED:
        return fit, PilotCheck(missed, 0, missed, found)
    mended, added = _mended(fit, rays, hit, light)
    return mended, PilotCheck(missed, added, _share(light, _check_light(wide, mended, rays, hit)[1]), found)


def _check_light(wide: EdgeBand, fit, rays: RayBatch, hit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flux each check photon brought to the edge (0 for a miss), whether it crossed P outside the fit's
    aimed rings): the check photons were drawn in `wide`, so each carries 1 / its density there."""
    wl = np.asarray(rays.wavelength, np.int64)
    q = wide.density(*wide.crossing(rays.origin, rays.direction), wl)
    light = np.where(hit & (q > 0), 1.0 / np.where(q > 0, q, 1.0), 0.0)
    return light, hit & ~(fit.density(*fit.crossing(rays.origin, rays.direction), wl) > 0)


def _share(light: np.ndarray, which: np.ndarray) -> float:
    total = float(light.sum())
    return float(light[which].sum()) / total if total > 0 else 0.0


def _mended(fit, rays: RayBatch, hit: np.ndarray, light: np.ndarray) -> tuple[EdgeBand | EdgeRings, int]:
    """The fit's rings plus rings fitted to the check's hits outside them; shares by the check's light
    each ring's support holds (first ring first); rings that hold none dropped (`_checked`)."""
    old = fit.rings if isinstance(fit, EdgeRings) else (fit,)
    wl = np.asarray(rays.wavelength, np.int64)
    rho, phi = fit.crossing(rays.origin, rays.direction)
    rings, left, added = list(old), hit.copy(), 0
    for ring in old:
        left &= ~(ring.density(rho, phi, wl) > 0)
    while added < MAX_RINGS and np.count_nonzero(left) >= MIN_HITS:
        coef, spread = robust_fit(_basis(phi[left]), rho[left])
        if coef is None:
            break
        n_wl = len(old[0].coef)
        ring = _with_azimuths(EdgeBand(old[0].centre, old[0].d0, np.tile(coef, (n_wl, 1)),
                                       np.full(n_wl, max(HALF_WIDTH_SIGMAS * spread, 1e-4)),
                                       np.full(N_PHI, 1.0 / N_PHI)), rays, hit)
        on = left & (ring.density(rho, phi, wl) > 0)
        if not on.any():
            break
        rings.append(ring)
        added += 1
        left &= ~on
    held, taken = [], np.zeros(len(hit), bool)
    for ring in rings:
        inside = hit & ~taken & (ring.density(rho, phi, wl) > 0)
        held.append(float(light[inside].sum()))
        taken |= inside
    kept = [(ring, h) for ring, h in zip(rings, held) if h > 0]
    if not kept:
        return fit, 0
    if len(kept) == 1:
        return kept[0][0], added
    total = sum(h for _, h in kept)
    return EdgeRings(tuple(r for r, _ in kept), tuple(h / total for _, h in kept)), added


def entrance_pupil(scene, tags: np.ndarray) -> tuple[float, float] | None:
    """(z, radius) of the paraxial image of the edge's rim through the optics in front of it (the
    entrance pupil when the edge is the stop's), or None. Two paraxial rays from the first surface:
    y_s = A y₀ + B ν₀ at the rim's plane; the chief ray (y_s = 0) crosses the axis at z₀ + n₀ B / A."""
    z_s, r_s = edge_rim(scene, tags)
    front = sorted((s for s in scene.optical if s.z_vertex < z_s), key=lambda s: s.z_vertex)
    if not front:
        return z_s, r_s
    n0, n = float(np.atleast_1d(front[0].n_before)[0]), float(np.atleast_1d(front[-1].n_after)[0])
    ends = []
    for y, nu in ((1.0, 0.0), (0.0, 1.0)):
        y, nu, z = paraxial_trace(front, y, nu, front[0].z_vertex)
        ends.append(y + (z_s - z) * nu / n)
    a, b = ends
    if abs(a) < 1e-12:
        return None
    z_ep, r_ep = front[0].z_vertex + n0 * b / a, abs(r_s / a)
    return (z_ep, r_ep) if math.isfinite(z_ep) and math.isfinite(r_ep) and r_ep > 0 else None


def aims_at_edge(scene, broad: np.ndarray) -> bool:
    """Photons are worth aiming at the diaphragm edge: it is the only face that scatters (case 2:
    aiming would starve the faces that carry most of the light) and the source is the sun or a
    collimated beam. Whether the pilot then finds the edge lit is `edge_band`'s answer."""
    tags = edge_tags(scene, broad)
    others = np.setdiff1d(np.flatnonzero(scattering_tags(scene)), tags)
    return len(tags) > 0 and not len(others) and scene.source.at_infinity


def _pilot(scene, tracer, broad, seed, n_photons):
    if not aims_at_edge(scene, broad):
        return None
    tags = edge_tags(scene, broad)
    band = first_band(scene, tags)
    if band is None:
        return None
    rays, hit = _stage_one(scene, tracer, band, tags, seed, n_photons)
    n_wl = len(scene.wavelengths_um)
    fit = _fit(rays, hit, band.centre, np.asarray(band.d0), n_wl, per_wavelength=False)
    if fit is None:
        return None
    # Stage 2: the stage-1 fit with a band twice its width (each ring), one ring per wavelength.
    band2 = _doubled(fit)
    rays, hit = _pilot_photons(scene, tracer, band2, tags, seed, "photon-pilot", 1,
                               np.arange(n_photons, 2 * n_photons, dtype=np.int64))
    return _fit(rays, hit, band.centre, np.asarray(band.d0), n_wl, per_wavelength=True) or fit


def _doubled(fit: EdgeBand | EdgeRings) -> EdgeBand | EdgeRings:
    """The fit with each ring's band twice as wide (stage 2's proposal)."""
    if isinstance(fit, EdgeRings):
        return EdgeRings(tuple(_doubled(r) for r in fit.rings), fit.share)
    return EdgeBand(fit.centre, fit.d0, fit.coef, 2.0 * fit.half_width, fit.pmf)


def first_band(scene, tags) -> EdgeBand | None:
    """The pilot's stage-1 proposal: the annulus 0.85 r_ep cos θ … 1.15 r_ep around the paraxial
    entrance pupil (its projection on P is an ellipse of axes r_ep and r_ep cos θ), one ring for all
    wavelengths. ~40 of 10⁵ photons meet the edge there on case 1 at 7°, ~14 at 3° (`_stage_one`)."""
    pupil = entrance_pupil(scene, tags)
    if pupil is None:
        return None
    z_ep, r_ep = pupil
    d0 = np.asarray(scene.source.direction, np.float64)
    n_wl = len(scene.wavelengths_um)
    lo, hi = 0.85 * r_ep * abs(float(d0[2])), 1.15 * r_ep
    return EdgeBand((0.0, 0.0, z_ep), tuple(d0), np.tile(np.r_[0.5 * (lo + hi), np.zeros(2 * _K)], (n_wl, 1)),
                    np.full(n_wl, 0.5 * (hi - lo)), np.full(N_PHI, 1.0 / N_PHI))


def _stage_one(scene, tracer, band, tags, seed, n_photons):
    """Stage 1's photons and hits: rounds of n_photons until MIN_HITS met the edge, at most
    PILOT_ROUNDS (an edge the sun lights through a narrower ring, e.g. closer to the axis, needs
    more photons to be found; without its band a pass reaches it ~10⁴ times more rarely), giving
    up after DARK_ROUNDS without any hit (an edge the sun does not reach)."""
    rays, hit = _pilot_photons(scene, tracer, band, tags, seed, "photon-pilot", 0,
                               np.arange(n_photons, dtype=np.int64))
    batches, hits = [rays], [hit]
    for r in range(1, PILOT_ROUNDS):
        found = sum(int(h.sum()) for h in hits)
        if found >= MIN_HITS or (found == 0 and r >= DARK_ROUNDS):
            break
        rays, hit = _pilot_photons(scene, tracer, band, tags, seed, "photon-pilot/more", r,
                                   np.arange(r * n_photons, (r + 1) * n_photons, dtype=np.int64))
        batches.append(rays)
        hits.append(hit)
    return RayBatch.concatenate(batches), np.concatenate(hits)


def _pilot_photons(scene, tracer, band, tags, seed, purpose, index, ids):
    """Pilot photons `ids` started so that they cross P in `band` (numbers from `purpose`'s stream
    `index`), and which of them met the edge (a FACE event on one of `tags`)."""
    rays, _ = scene.source.emit(len(ids), Streams(seed, purpose + "/emit", ids))
    pick = stream(seed, purpose + "/ring", index).random(len(ids)) if isinstance(band, EdgeRings) else None
    p = band.sample(stream(seed, purpose, index).random((len(ids), 2)), rays.wavelength, pick)
    start = _back_to_disc(p, rays.direction, np.asarray(scene.source.disc.centre), np.asarray(band.d0))
    rays = RayBatch.make(start, rays.direction, wavelength=rays.wavelength, ids=ids)
    step = tracer.next_event(rays, Streams(seed, purpose + "/trace", ids))
    hit = np.zeros(len(ids), bool)
    hit[step.id[(step.kind == FACE) & np.isin(step.tag, tags) & (step.weight > 0)] - ids[0]] = True
    return rays, hit


def _fit(rays: RayBatch, hit: np.ndarray, centre, d0: np.ndarray, n_wl: int,
         per_wavelength: bool) -> EdgeBand | EdgeRings | None:
    """EdgeBand from the pilot photons and which of them met the edge: the plane's shift along d₀
    with the narrowest ring, then ρ*(φ) and h (per wavelength, or one for all from half as many
    hits), and the azimuth histogram; EdgeRings when the edge is lit through several (`_more_rings`)."""
    wl = np.asarray(rays.wavelength, np.int64) if per_wavelength else np.zeros(len(hit), np.int64)
    n_fit = n_wl if per_wavelength else 1
    if any(np.count_nonzero(hit & (wl == k)) < MIN_HITS * (1 if per_wavelength else 0.5) for k in range(n_fit)):
        return None
    some = np.flatnonzero(hit)[::max(1, int(np.count_nonzero(hit)) // _SCAN_HITS)]
    shift, step = 0.0, float(_PLANE_SHIFTS[1] - _PLANE_SHIFTS[0])
    for shifts in (_PLANE_SHIFTS, None, None):  # coarse, then twice ±2 steps at a fifth of the step
        if shifts is None:
            step /= 5.0
            shifts = shift + step * np.arange(-10, 11)
        spread = [_ring(*_crossing(_shifted(centre, d0, z), d0, rays.origin[some], rays.direction[some]),
                        wl[some], n_fit)[1] for z in shifts]
        spread = [np.inf if s is None else float(s.sum()) for s in spread]
        shift = float(shifts[int(np.argmin(spread))])
        if not np.isfinite(min(spread)):
            return None
    c = _shifted(centre, d0, shift)
    coef, sigma = _ring(*_crossing(c, d0, rays.origin[hit], rays.direction[hit]), wl[hit], n_fit)
    if coef is None:
        return None
    coef, sigma = np.broadcast_to(coef, (n_wl, coef.shape[1])).copy(), np.broadcast_to(sigma, (n_wl,)).copy()
    wl = np.asarray(rays.wavelength, np.int64)
    band = _with_azimuths(EdgeBand(c, tuple(d0), coef, np.maximum(HALF_WIDTH_SIGMAS * sigma, 1e-4),
                                   np.full(N_PHI, 1.0 / N_PHI)), rays, hit)
    return _more_rings(band, rays, hit, wl)


def _with_azimuths(band: EdgeBand, rays: RayBatch, hit: np.ndarray) -> EdgeBand:
    """The band with its azimuth histogram: hit rate per bin among the pilot photons that crossed P
    inside it."""
    wl = np.asarray(rays.wavelength, np.int64)
    rho, phi = band.crossing(rays.origin, rays.direction)
    inside = band.density(rho, phi, wl) > 0
    b = azimuth_bin(phi)
    tried = np.bincount(b[inside], minlength=N_PHI)
    got = np.bincount(b[inside & hit], minlength=N_PHI)
    return EdgeBand(band.centre, band.d0, band.coef, band.half_width, azimuth_pmf(tried, got))


def _more_rings(band: EdgeBand, rays: RayBatch, hit: np.ndarray, wl: np.ndarray) -> EdgeBand | EdgeRings:
    """The band, or the rings through which the edge is lit when the ring's fit left out at least
    MIN_HITS pilot hits (beyond RING_SIGMAS of its residual spread: `targets.robust_fit`) that lie on
    another ring of their own (a fit to them keeps MIN_HITS within RING_SIGMAS of a spread at most
    RING_SPREAD times the first ring's); at most MAX_RINGS. Each ring's share of the aimed photons is
    its share of the hits the rings explain."""
    rho, phi = band.crossing(rays.origin, rays.direction)
    sigma = band.half_width[np.clip(wl, 0, len(band.half_width) - 1)] / HALF_WIDTH_SIGMAS
    explained = hit & (np.abs(rho - band.radius(phi, wl)) <= RING_SIGMAS * sigma)
    left = hit & ~explained
    rings, counts = [band], [int(explained.sum())]
    while len(rings) < MAX_RINGS and np.count_nonzero(left) >= MIN_HITS:
        coef, spread = robust_fit(_basis(phi[left]), rho[left])
        if coef is None or spread > RING_SPREAD * float(sigma.max()):
            break  # scattered hits, not a ring
        on = left & (np.abs(rho - _basis(phi) @ coef) <= RING_SIGMAS * spread + 1e-9)
        if np.count_nonzero(on) < MIN_HITS:
            break
        n_wl = len(band.coef)
        ring = EdgeBand(band.centre, band.d0, np.tile(coef, (n_wl, 1)),
                        np.full(n_wl, max(HALF_WIDTH_SIGMAS * spread, 1e-4)), np.full(N_PHI, 1.0 / N_PHI))
        rings.append(_with_azimuths(ring, rays, hit))
        counts.append(int(on.sum()))
        left &= ~on
    if len(rings) == 1:
        return band
    return EdgeRings(tuple(rings), tuple(float(k) / sum(counts) for k in counts))


def _shifted(centre, d0: np.ndarray, shift: float) -> tuple[float, float, float]:
    """The plane P's centre moved by `shift` mm along d₀."""
    return tuple(float(x) for x in np.asarray(centre) + shift * d0)


def _crossing(centre, d0, origin: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ρ, φ) (N,) where rays cross the plane through `centre` normal to d0, in its polar coordinates
    (axes `orthonormal_basis(d0)`)."""
    c, d0 = np.asarray(centre), np.asarray(d0)
    e1, e2 = orthonormal_basis(d0)
    t = ((c - origin) @ d0) / (direction @ d0)
    p = origin + t[:, None] * direction - c
    a, b = p @ e1, p @ e2
    return np.hypot(a, b), np.arctan2(b, a)


def _back_to_disc(p: np.ndarray, d: np.ndarray, centre: np.ndarray, d0: np.ndarray) -> np.ndarray:
    """Points p (N, 3) moved back along their directions d to the source disc's plane (normal d0
    through its centre)."""
    return p - (((p - centre) @ d0) / (d @ d0))[:, None] * d


def _ring(rho, phi, wl, n_wl):
    """Per wavelength, least-squares ρ*(φ) coefficients (n_wl, 2K+1) and residual spread (n_wl,),
    refitted without hits far from the ring (other paths to the edge); (None, None) if not finite."""
    coef, sigma = np.zeros((n_wl, 2 * _K + 1)), np.zeros(n_wl)
    for k in range(n_wl):
        m = wl == k
        ck, s = robust_fit(_basis(phi[m]), rho[m])
        if ck is None:
            return None, None
        coef[k], sigma[k] = ck, s
    return coef, sigma


__all__ = ["EdgeBand", "EdgeRings", "PilotCheck", "COMPONENTS", "CHECK_MISSED", "emission_component", "aims_at_edge",
           "edge_band", "entrance_pupil", "guided_photons", "pilot_check", "pilot_check_diagnostics", "tally_edge_flux",
           "UNIFORM_SHARE", "WIDE_SHARE", "WIDE_FACTOR"]
