"""A learned backward target for the thin diaphragm edge: the stop rim as really seen from x.

Why. A backward ray meets the 50 µm diaphragm edge only if it reaches the stop radius
within the edge's axial width: a radial window ~10 µm wide at the exit-pupil plane. The
paraxial rim annulus (`view_map.stop_rim_target`, ±2 %, ~1.2 mm) is ~100× wider, and the
window's true place moves with the detector point and the wavelength (pupil aberration and
lateral colour shift it by ~0.1 mm). So most rim samples miss.

What. A deterministic *pilot* (its own stream, `stream(seed, "pilot", 0)`, computed once
per (scene, tracer, seed) and cached in the process, never from other passes) traces
backward samples aimed at the paraxial rim and records where the ones that made a hit
point on the edge crossed the rim plane. A least-squares fit gives the window's centre

    ρ*(s, Δφ, λ) = Σ_jk a_jkλ s^j cos(k Δφ),   s = r_d / r_max, j ≤ 2, k ≤ 3

(ρ radius on the rim plane, Δφ its azimuth relative to the detector point's, r_d the
detector point's radius; even in Δφ by the mirror symmetry through the axis and x) and
its half width h_λ = 2.5 × the residual spread. A second pilot stage samples from that
fit (wider band) to refine a and the azimuth histogram p(Δφ | detector zone).

The target `LearnedRim` samples Δφ from p(Δφ | zone) (36 bins with a floor) and ρ
uniform in [ρ* − h, ρ* + h]; its density per unit area on the plane is

    p_A(q | x, λ) = p(Δφ | zone) / (2 h_λ ρ)   inside the band, 0 outside,

evaluated exactly for every backward sample in the mixture (`exit_sampler.mixture_pdf`),
so the estimator stays unbiased whatever the fit's quality; the disc and the hemisphere
stay in the mixture for all other light (docs/bidirectional.md).

Near misses. A share `WIDE_SHARE` of the band's samples is drawn in a band `WIDE_FACTOR` times as
wide, every azimuth alike (the photon side's wide band, `photon_target`). At some detector points
the window is wider than the fit's mean spread, and a sample that meets the edge just outside
±h was a disc sample carrying ~23 000 times a band sample's τ: on case 1 (seed 21, pass 1) one
such hit point, 1.01 h outside the band at Δφ = 168°, s = 0.73, held 76 % of the pass's light and
made the pass read 4.35 times the median. In the wide band it carries ~40 times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.integrators.exit_sampler import sample_toward_exit
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import stream
from lensmount.trace.tracer import FACE

N_ZONES = 8  # detector radius zones for the azimuth histogram
N_DPHI = 36  # azimuth bins over [−π, π)
FLOOR = 0.1  # share of the azimuth pmf spread uniformly (keeps every azimuth reachable)
HALF_WIDTH_SIGMAS = 2.5  # final band half width in residual standard deviations (window ≈ ±√3 σ)
PILOT_RAYS = 100_000  # per pilot stage
MIN_HITS = 40  # per wavelength, to fit the 12 coefficients; fewer: no learned target
_J, _K = 3, 4  # powers of s, harmonics of Δφ
WIDE_SHARE = 0.2  # band samples drawn in the wide band (near misses of the fit)
WIDE_FACTOR = 8.0  # its half width in h

_CACHE: dict[tuple, tuple] = {}
PILOTS_KEPT = 1024  # entries of one tracer in a pilot cache (`cached_pilot`): a sweep has ≤ 1000 angles


def _basis(s: np.ndarray, dphi: np.ndarray) -> np.ndarray:
    """(N, J·K) columns s^j cos(k Δφ), k-major (cos kΔφ by the Chebyshev recurrence: one cos call)."""
    c1 = np.cos(dphi)
    cosk = [np.ones_like(c1), c1]
    for _ in range(2, _K):
        cosk.append(2.0 * c1 * cosk[-1] - cosk[-2])
    powers = [np.ones_like(s), s]
    for _ in range(2, _J):
        powers.append(powers[-1] * s)
    return np.stack([cosk[k] * powers[j] for k in range(_K) for j in range(_J)], axis=1)


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angle wrapped into [−π, π)."""
    return np.mod(angle + math.pi, 2.0 * math.pi) - math.pi


def azimuth_bin(angle: np.ndarray) -> np.ndarray:
    """The histogram bin (0 … N_DPHI − 1) of angles in [−π, π)."""
    return np.clip(((angle + math.pi) * (N_DPHI / (2 * math.pi))).astype(np.int64), 0, N_DPHI - 1)


def azimuth_pmf(tried: np.ndarray, got: np.ndarray) -> np.ndarray:
    """Azimuth probabilities over the last axis from the pilot's samples per bin (`tried`) and those
    that met the edge (`got`): the hit rate, smoothed over neighbouring bins, with a FLOOR spread
    uniformly so that every azimuth stays reachable (rows sum to 1)."""
    rate = got / np.maximum(tried, 1)
    rate = 0.5 * rate + 0.25 * (np.roll(rate, 1, axis=-1) + np.roll(rate, -1, axis=-1))
    total = rate.sum(axis=-1, keepdims=True)
    shape = np.where(total > 0, rate / np.where(total > 0, total, 1.0), 1.0 / N_DPHI)
    pmf = (1.0 - FLOOR) * shape + FLOOR / N_DPHI
    return pmf / pmf.sum(axis=-1, keepdims=True)


def cached_pilot(cache: dict, key: tuple, scene, tracer, pilot):
    """`pilot()` once per key in this process. The entry keeps scene and tracer alive, so their ids
    (in the key) cannot be reused by other objects while it exists. Beyond a few entries only those of
    this tracer are kept: they share its mesh and BVH (a pst sweep's worker keeps one photon pilot per
    angle, whose scenes differ in their source alone), while each other tracer would hold its own."""
    if key not in cache:
        if len(cache) > 8:
            for old in [k for k, entry in cache.items() if entry[1] is not tracer]:
                del cache[old]
        if len(cache) >= PILOTS_KEPT:
            cache.clear()
        cache[key] = (scene, tracer, pilot())
    return cache[key][2]


@dataclass(frozen=True)
class LearnedRim:
    """The band around the edge's window on the plane z (normal to the axis), per wavelength.

    coef : (W, J·K) fit of ρ*; half_width : (W,) mm; r_max : detector radius scale (mm);
    pmf : (N_ZONES, N_DPHI) azimuth probabilities per detector zone (rows sum to 1);
    wide_share : share of samples in the band WIDE_FACTOR times as wide, every azimuth alike
        (module docstring; the pilot's own proposal has none).
    """

    z: float
    facing: float
    coef: np.ndarray
    half_width: np.ndarray
    r_max: float
    pmf: np.ndarray
    wide_share: float = WIDE_SHARE

    def _frame(self, x: np.ndarray, wavelength):
        """Per-sample s, detector azimuth, zone, wavelength index (0 when None)."""
        r_d = np.hypot(x[:, 0], x[:, 1])
        s = np.minimum(r_d / self.r_max, 1.0)
        zone = np.minimum((s * N_ZONES).astype(np.int64), N_ZONES - 1)
        wl = np.zeros(len(x), np.int64) if wavelength is None else np.asarray(wavelength, np.int64)
        wl = np.clip(wl, 0, len(self.coef) - 1)
        return s, np.arctan2(x[:, 1], x[:, 0]), zone, wl

    def centre(self, s: np.ndarray, dphi: np.ndarray, wl: np.ndarray) -> np.ndarray:
        """(N,) ρ* in mm."""
        return np.einsum("nk,nk->n", _basis(s, dphi), self.coef[wl])

    def area_pdf(self, x: np.ndarray, q: np.ndarray, wavelength=None) -> np.ndarray:
        """(N,) density per unit area at q (N,3) on the plane, for samples from x (N,3)."""
        s, az, zone, wl = self._frame(x, wavelength)
        rho = np.hypot(q[:, 0], q[:, 1])
        dphi = _wrap(np.arctan2(q[:, 1], q[:, 0]) - az)  # in [−π, π)
        b = azimuth_bin(dphi)
        h = self.half_width[wl]
        off = np.abs(rho - self.centre(s, dphi, wl))
        per_rho = 1.0 / (2.0 * math.pi * 2.0 * h * np.where(rho > 0, rho, 1.0))
        narrow = np.where(off <= h, self.pmf[zone, b] * N_DPHI * per_rho, 0.0)
        wide = np.where(off <= WIDE_FACTOR * h, per_rho / WIDE_FACTOR, 0.0)
        return np.where(rho > 0, (1.0 - self.wide_share) * narrow + self.wide_share * wide, 0.0)

    def sample_points(self, x: np.ndarray, u: np.ndarray, wavelength=None) -> np.ndarray:
        """(N, 3) points: Δφ from the zone's histogram (u[:,1]), ρ uniform in the band (u[:,0]); for
        u[:,0] < wide_share, Δφ uniform and ρ uniform in the wide band (u[:,0] rescaled: one number
        picks the component and places ρ)."""
        s, az, zone, wl = self._frame(x, wavelength)
        wide = u[:, 0] < self.wide_share
        u0 = np.where(wide, u[:, 0] / max(self.wide_share, 1e-300),
                      (u[:, 0] - self.wide_share) / (1.0 - self.wide_share))
        cdf = np.cumsum(self.pmf, axis=1)
        cdf[:, -1] = 1.0
        flat = (np.arange(N_ZONES)[:, None] + cdf).ravel()  # zone k's cdf shifted to (k, k+1]
        idx = np.searchsorted(flat, zone + u[:, 1], side="right")
        idx = np.minimum(idx, zone * N_DPHI + N_DPHI - 1)
        b = idx - zone * N_DPHI
        lo = np.where(b > 0, cdf[zone, np.maximum(b - 1, 0)], 0.0)
        p = self.pmf[zone, b]
        frac = np.clip((u[:, 1] - lo) / np.where(p > 0, p, 1.0), 0.0, 1.0 - 1e-12)  # the rest of u, reused
        dphi = np.where(wide, -math.pi + 2.0 * math.pi * u[:, 1], -math.pi + (b + frac) * (2 * math.pi / N_DPHI))
        rho = self.centre(s, dphi, wl) + np.where(wide, WIDE_FACTOR, 1.0) * self.half_width[wl] * (2.0 * u0 - 1.0)
        rho = np.maximum(rho, 0.0)
        phi = az + dphi
        return np.stack([rho * np.cos(phi), rho * np.sin(phi), np.full(len(x), self.z)], axis=1)


def edge_tags(scene, broad: np.ndarray) -> np.ndarray:
    """Tags of broad faces with role `diaphragm-edge` (as `view_map.stop_rim_target`)."""
    return np.array([k for k, t in enumerate(scene.mesh.tag_table)
                     if t.role == "diaphragm-edge" and k < len(broad) and broad[k]], np.int64)


def edge_rim(scene, tags) -> tuple[float, float]:
    """(z, radius) of the diaphragm edge: the mean z and distance from the axis of its vertices."""
    tri = scene.mesh.triangles[np.isin(scene.mesh.tags, tags)]
    v = scene.mesh.vertices[np.unique(tri)]
    return float(v[:, 2].mean()), float(np.hypot(v[:, 0], v[:, 1]).mean())


def paraxial_trace(surfaces, y: float, nu: float, z: float) -> tuple[float, float, float]:
    """(y, nu, z) of a paraxial ray (height y, reduced angle nu = n u at z) after `surfaces` in
    order of z (wavelength 0): transfer to each vertex, then refraction by its power."""
    for s in surfaces:
        n1, n2 = float(np.atleast_1d(s.n_before)[0]), float(np.atleast_1d(s.n_after)[0])
        y = y + (s.z_vertex - z) * nu / n1
        z = s.z_vertex
        nu = nu - y * (n2 - n1) * s.profile.vertex_curvature
    return y, nu, z


def robust_fit(a: np.ndarray, r: np.ndarray):
    """Least-squares coefficients of r ≈ a c and the residual spread, refitted three times without
    the points beyond 4 spreads (other paths to the edge); (None, None) if not finite."""
    keep = np.ones(len(r), bool)
    for _ in range(3):
        c, *_ = np.linalg.lstsq(a[keep], r[keep], rcond=None)
        res = r - a @ c
        sigma = float(np.std(res[keep]))
        keep = np.abs(res) <= 4.0 * sigma + 1e-9
    if not (np.all(np.isfinite(c)) and math.isfinite(sigma)):
        return None, None
    return c, sigma


def learned_rim(scene, tracer, det, broad: np.ndarray, seed: int, rim, n_rays: int = PILOT_RAYS):
    """The pilot's LearnedRim for (scene, tracer, seed), or None (no rim, too few pilot hits).

    rim : the paraxial ExitDisc annulus (`view_map.stop_rim_target`), the pilot's first proposal.
    Cached per process; a pure function of its arguments, so every pass and worker gets the same.
    """
    # The mesh's id catches a scene whose geometry was swapped.
    key = (id(scene), id(scene.mesh), id(tracer), int(seed), int(n_rays), rim)
    return cached_pilot(_CACHE, key, scene, tracer, lambda: _pilot(scene, tracer, det, broad, int(seed), rim,
                                                                   int(n_rays)))


def _pilot(scene, tracer, det, broad, seed, rim, n_rays):
    tags = edge_tags(scene, broad)
    if rim is None or len(tags) == 0:
        return None
    rng = stream(seed, "pilot", 0)
    n_wl = len(scene.wavelengths_um)
    r_max = math.hypot(det.width / 2, det.height / 2)
    # Stage 1: the paraxial annulus. Stage 2: the stage-1 fit with a band twice the final one.
    proposal = rim
    fit = None
    for stage in range(2):
        pixel = rng.integers(0, det.nx * det.ny, n_rays)
        x = det.sample_points(pixel, rng.random((n_rays, 2)))
        wl = rng.integers(0, n_wl, n_rays)
        omega, w = sample_toward_exit(x, rng.random((n_rays, 3)), [proposal], [1.0], wl)
        live = w > 0
        rays = RayBatch.make(x[live], omega[live], weight=w[live], wavelength=wl[live],
                             ids=np.flatnonzero(live))
        step = tracer.next_event(rays, rng)
        hit = (step.kind == FACE) & np.isin(step.tag, tags) & (step.weight > 0)
        i = step.id[hit].astype(np.int64)
        new = _fit(x, omega, wl, i, rim.z, rim.facing, r_max, n_wl, stage)
        if new is None:
            break
        fit = new
        proposal = LearnedRim(fit.z, fit.facing, fit.coef, 2.0 * fit.half_width, r_max, fit.pmf, wide_share=0.0)
    return fit


def _fit(x, omega, wl, hit, z, facing, r_max, n_wl, stage):
    """LearnedRim from the samples (x, ω, λ) and the indices `hit` of those that met the edge."""
    if len(hit) == 0:
        return None
    t = (z - x[:, 2]) / np.where(np.abs(omega[:, 2]) > 1e-300, omega[:, 2], 1e-300)
    q = x + t[:, None] * omega
    rho = np.hypot(q[:, 0], q[:, 1])
    az = np.arctan2(x[:, 1], x[:, 0])
    dphi = _wrap(np.arctan2(q[:, 1], q[:, 0]) - az)
    s = np.minimum(np.hypot(x[:, 0], x[:, 1]) / r_max, 1.0)
    coef = np.zeros((n_wl, _J * _K))
    half = np.zeros(n_wl)
    for k in range(n_wl):
        m = hit[wl[hit] == k]
        if len(m) < MIN_HITS:
            return None
        c, sigma = robust_fit(_basis(s[m], dphi[m]), rho[m])
        if c is None:
            return None
        coef[k], half[k] = c, max(HALF_WIDTH_SIGMAS * sigma, 1e-4)
    # Azimuth histogram per zone: hit rate = hits / samples per (zone, bin), smoothed, with a floor.
    zone = np.minimum((s * N_ZONES).astype(np.int64), N_ZONES - 1)
    cell = zone * N_DPHI + azimuth_bin(dphi)
    tried = np.bincount(cell, minlength=N_ZONES * N_DPHI).reshape(N_ZONES, N_DPHI)
    got = np.bincount(cell[hit], minlength=N_ZONES * N_DPHI).reshape(N_ZONES, N_DPHI)
    return LearnedRim(float(z), float(facing), coef, half, float(r_max), azimuth_pmf(tried, got))


__all__ = ["LearnedRim", "learned_rim", "edge_tags", "edge_rim", "paraxial_trace", "robust_fit", "azimuth_bin",
           "azimuth_pmf", "cached_pilot", "N_DPHI", "FLOOR", "WIDE_SHARE", "WIDE_FACTOR"]
