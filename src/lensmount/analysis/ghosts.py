"""Ghost analysis: every two-reflection path between optical surfaces, traced deterministically.

A ghost (i, j), i < j, is the light that crosses surfaces 1 … j, reflects at j, goes
back through j−1 … i+1, reflects at i and then crosses i+1 … S to the detector. Each
pair is traced on its own with real rays and the real Fresnel (or coating) reflectance
and transmittance per wavelength at every crossing, so a report per pair costs one
sequential trace instead of the millions of photons a stochastic reflection branch
spends to find the same light.

Rays: a square lattice over the first surface's clear aperture (in the plane of its
vertex, each ray carrying h² cos θ of flux per unit E_sun), times the scene's
wavelengths with their source weights; for the sun, each ray takes its direction from a
low-discrepancy (R2) sequence over the solar disc, so a focused ghost is the sun's image
as it should be, and the result is still the same on every run. Vignetting is by the
clear semi-diameters and, given the scene's tracer, by the mount itself: every straight
segment of a ghost path is checked against the mesh (barrel walls, spacers, the
diaphragm, the housing), with the same Embree intersection the simulation uses.

Per pair: flux on the detector (as a fraction of the flux entering the entrance pupil,
the `stray_fraction` of a simulation), its share of all ghost flux, the peak irradiance
E/E_sun (pixel counts smoothed until the estimate holds ≥ 25 rays, so a defocused ghost's
peak is not one ray's noise), the footprint (centroid and the radius holding 90 % of the
flux), and the distance of the ghost's best focus from the detector plane (least-squares
waist of the bundle; positive behind the detector, None for a collimated ghost).
Pairs whose reflectance is zero at every wavelength (perfect AR, or a dummy surface with the
same medium on both sides, such as the stop plane) are skipped before any ray is traced.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lensmount.trace.interfaces import fresnel_rt, reflect, refract

RAYS_ACROSS = 151  # lattice points across the first clear aperture
MIN_RAYS_PER_PEAK = 25
_R2 = (0.7548776662466927, 0.5698402909980532)  # the R2 sequence's generators (plastic number)


@dataclass
class GhostPair:
    """One two-reflection ghost. first, second: 1-based surface numbers where it reflects (first < second)."""

    first: int
    second: int
    fraction: float  # detector flux / flux entering the entrance pupil
    share: float  # of all ghost flux on the detector
    peak_irradiance: float  # E / E_sun
    focus_from_detector_mm: float | None
    centroid_mm: tuple[float, float]
    radius90_mm: float
    image: np.ndarray = field(repr=False)  # (ny, nx) E / E_sun

    def to_dict(self) -> dict:
        return {"surfaces": [self.first, self.second], "fraction": self.fraction, "share": self.share,
                "peak_irradiance": self.peak_irradiance, "focus_from_detector_mm": self.focus_from_detector_mm,
                "centroid_mm": list(self.centroid_mm), "radius90_mm": self.radius90_mm}


@dataclass
class GhostReport:
    pairs: list[GhostPair]  # ranked by peak irradiance, strongest first
    skipped: list[tuple[int, int]]  # pairs with no reflectance (perfect AR)
    total_fraction: float
    rays_per_pair: int

    def to_dict(self) -> dict:
        return {"pairs": [p.to_dict() for p in self.pairs], "skipped_no_reflectance": [list(s) for s in self.skipped],
                "total_fraction": self.total_fraction, "rays_per_pair": self.rays_per_pair,
                "ranked_by": "peak_irradiance"}


def ghost_report(scene, tracer=None, rays_across: int = RAYS_ACROSS) -> GhostReport:
    """Trace every two-reflection ghost of `scene` (see the module docstring).

    tracer : the scene's `Tracer`, whose mesh blocks ghost light where the mount's walls do;
        None traces the prescription alone (clear apertures only).
    """
    walls = NoWalls() if tracer is None else Walls(tracer)
    surfaces = sorted(scene.optical, key=lambda s: s.index)
    det = scene.detector
    d0 = np.asarray(scene.source.direction, np.float64)
    aperture = scene.entrance_pupil_area_mm2 * max(d0[2], 0.0)
    pairs, skipped = [], []
    if d0[2] <= 0.0 or aperture <= 0.0 or len(surfaces) < 2:  # no light enters from behind the lens
        return GhostReport([], [], 0.0, 0)
    origins, directions, flux, wl = _launch(scene, surfaces[0], d0, rays_across)
    for b in range(len(surfaces)):
        for a in range(b):
            if not (_reflects(surfaces[a]) and _reflects(surfaces[b])):
                skipped.append((surfaces[a].index + 1, surfaces[b].index + 1))
                continue
            p, d, w = _trace_pair(surfaces, a, b, origins, directions, flux, wl, scene.wavelengths_um, det, walls)
            pairs.append(_pair(surfaces[a].index + 1, surfaces[b].index + 1, p, d, w, det, aperture))
    total = sum(g.fraction for g in pairs)
    for g in pairs:
        g.share = g.fraction / total if total > 0 else 0.0
    pairs = [g for g in pairs if g.fraction > 0]
    pairs.sort(key=lambda g: g.peak_irradiance, reverse=True)
    return GhostReport(pairs, skipped, total, len(origins))


def _reflects(surface) -> bool:
    """Can this surface reflect outside total internal reflection? Perfect AR and R=0 cannot, nor can a
    surface with the same medium on both sides (the stop plane in air is no interface to coat)."""
    c = surface.coating
    if np.array_equal(surface.n_before, surface.n_after):
        return False
    return not (c.kind == "perfect-ar" or (c.kind == "constant" and c.reflectance == 0.0))


def _launch(scene, first, d0: np.ndarray, rays_across: int):
    """Lattice rays over the first clear aperture × wavelengths: origins, directions, flux, wavelength index."""
    radius = first.clear_semi_diameter
    h = 2.0 * radius / (rays_across - 1)
    g = np.linspace(-radius, radius, rays_across)
    x, y = np.meshgrid(g, g)
    keep = x * x + y * y <= radius * radius
    x, y = x[keep], y[keep]
    n = len(x)
    sag = first.profile.sag(np.array([0.0, radius * radius]))
    z_start = first.z_vertex + min(float(sag.min()), 0.0) - 1.0
    directions = _directions(scene.source, d0, n)
    # Back the rays off along their direction so that they cross z_start at the lattice points.
    origins = np.column_stack([x, y, np.full(n, z_start)]) - directions
    weights = np.asarray(scene.source.wavelength_weights, np.float64)
    weights = weights / weights.sum() if weights.sum() > 0 else np.full(len(weights), 1.0 / len(weights))
    n_wl = len(scene.wavelengths_um)
    weights = weights if len(weights) == n_wl else np.full(n_wl, 1.0 / n_wl)
    flux = np.concatenate([np.full(n, h * h * d0[2] * w) for w in weights])
    wl = np.repeat(np.arange(n_wl), n)
    return np.tile(origins, (n_wl, 1)), np.tile(directions, (n_wl, 1)), flux, wl


def _directions(source, d0: np.ndarray, n: int) -> np.ndarray:
    """n directions over the source's angular disc (R2 sequence), or d0 for a point source."""
    alpha = float(source.half_angle_rad)
    if alpha <= 0.0:
        return np.tile(d0, (n, 1))
    from lensmount.trace.sources import orthonormal_basis

    k = np.arange(1, n + 1)
    u1, u2 = (0.5 + _R2[0] * k) % 1.0, (0.5 + _R2[1] * k) % 1.0
    rho, psi = alpha * np.sqrt(u1), 2.0 * math.pi * u2
    e1, e2 = orthonormal_basis(d0)
    d = np.cos(rho)[:, None] * d0 + (np.sin(rho) * np.cos(psi))[:, None] * e1 + (np.sin(rho) * np.sin(psi))[:, None] * e2
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _trace_pair(surfaces, a: int, b: int, o, d, flux, wl, wavelengths_um, det, walls):
    """Rays through 0..b (reflect at b), back through b−1..a (reflect at a), on through a+1..S−1, to the
    detector plane. Returns the detector points, directions and fluxes of the rays that got there."""
    lam = np.asarray(wavelengths_um, np.float64)
    route = ([(k, "refract") for k in range(b)] + [(b, "reflect")] + [(k, "refract") for k in range(b - 1, a, -1)]
             + [(a, "reflect")] + [(k, "refract") for k in range(a + 1, len(surfaces))])
    o, d, w, wl = o.copy(), d.copy(), flux.copy(), wl.copy()
    n_from = np.zeros_like(o)  # normal of the surface each ray leaves (none at the start)
    for k, action in route:
        p, new_d, w, nrm = _interact(surfaces[k], o, d, w, wl, lam[wl], action)
        w = np.where(walls.blocked(o, p, n_from, w > 0), 0.0, w)
        live = w > 0  # carry only live lanes from here on: most ghost rays are vignetted early
        o, d, w, wl, n_from = p[live], new_d[live], w[live], wl[live], nrm[live]
    # To the detector plane; rays travelling away from it carry nothing.
    dz = d[:, 2]
    t = np.where(dz > 1e-12, (det.z - o[:, 2]) / np.where(dz > 1e-12, dz, 1.0), -1.0)
    w = np.where(t > 0, w, 0.0)
    p = o + np.maximum(t, 0.0)[:, None] * d
    w = np.where(walls.blocked(o, p, n_from, w > 0), 0.0, w)
    return p, d, w


def _interact(surface, o, d, w, wl, lam, action):
    """Meet `surface` within its clear aperture, then refract or reflect: (points, directions, flux, normals)."""
    local = o - np.array([0.0, 0.0, surface.z_vertex])
    t = surface.profile.intersect(local, d)
    hit = np.isfinite(t) & (t > 1e-9) & (w > 0)
    p = local + np.where(hit, t, 0.0)[:, None] * d
    hit &= p[:, 0] ** 2 + p[:, 1] ** 2 <= surface.clear_semi_diameter ** 2
    nrm = surface.profile.normal(p)
    forward = d[:, 2] > 0
    n1 = np.where(forward, surface.n_before[wl], surface.n_after[wl])
    n2 = np.where(forward, surface.n_after[wl], surface.n_before[wl])
    cos_i = np.abs(np.einsum("ij,ij->i", d, nrm))
    rs, rp, ts, tp = fresnel_rt(n1, n2, cos_i, surface.coating, lam)
    if action == "reflect":
        new_d, factor = reflect(d, nrm), 0.5 * (rs + rp)
    else:
        new_d, tir, _, _ = refract(d, nrm, n1 / n2)
        factor = np.where(tir, 0.0, 0.5 * (ts + tp))
    w = np.where(hit, w * factor, 0.0)
    return p + np.array([0.0, 0.0, surface.z_vertex]), np.where(hit[:, None], new_d, d), w, nrm


class Walls:
    """The mount as the ghost light meets it: a segment is blocked where a mechanical face of the
    scene's mesh lies on it (the real tracer's intersection, optical faces passed through)."""

    TOLERANCE_MM = 1e-3

    def __init__(self, tracer):
        self.tracer = tracer

    def blocked(self, start, end, start_normal, live):
        """(N,) bool: the segment start → end of each live ray crosses a mechanical face."""
        from lensmount.trace.rays import RayBatch

        out = np.zeros(len(start), bool)
        seg = end - start
        remaining = np.linalg.norm(seg, axis=1)
        todo = np.flatnonzero(live & (remaining > self.TOLERANCE_MM))
        o, n0 = start.copy(), start_normal.copy()
        d = seg / np.maximum(remaining, 1e-300)[:, None]
        for _ in range(8):  # optical faces met on the way (the segment's own end, a cemented neighbour) are passed
            if todo.size == 0:
                break
            h = self.tracer.intersect(RayBatch.make(o[todo], d[todo]), origin_normal=n0[todo])
            near = np.isfinite(h.t) & (h.t < remaining[todo] - self.TOLERANCE_MM)
            wall = near & (h.prim >= 0) & (h.surface < 0) | (near & h.lost)
            out[todo[wall]] = True
            again = near & (h.prim >= 0) & (h.surface >= 0)
            step = todo[again]
            o[step], n0[step] = h.point[again], h.normal[again]
            remaining[step] -= h.t[again]
            todo = step
        return out


class NoWalls:
    """Clear apertures only: the lens as the prescription describes it, without its mount."""

    @staticmethod
    def blocked(start, end, start_normal, live):
        return np.zeros(len(start), bool)


def _pair(first: int, second: int, p, d, w, det, aperture: float) -> GhostPair:
    pix = det.pixel_of(p)
    on = (pix >= 0) & (w > 0)
    image = np.bincount(pix[on], weights=w[on], minlength=det.nx * det.ny).reshape(det.ny, det.nx) / det.pixel_area
    flux = float(w[on].sum())
    if flux <= 0.0:
        return GhostPair(first, second, 0.0, 0.0, 0.0, None, (0.0, 0.0), 0.0, image)
    counts = np.bincount(pix[on], minlength=det.nx * det.ny).reshape(det.ny, det.nx)
    peak = _peak(image, counts)
    x, y, wt = p[on, 0], p[on, 1], w[on]
    cx, cy = float(np.average(x, weights=wt)), float(np.average(y, weights=wt))
    r = np.hypot(x - cx, y - cy)
    order = np.argsort(r)
    r90 = float(r[order][np.searchsorted(np.cumsum(wt[order]), 0.9 * flux)].item()) if len(r) else 0.0
    return GhostPair(first, second, flux / aperture, 0.0, peak, _focus(p[on], d[on], wt), (cx, cy), r90, image)


def _peak(image: np.ndarray, counts: np.ndarray) -> float:
    """Largest irradiance after smoothing with the smallest box that holds ≥ MIN_RAYS_PER_PEAK rays at the peak."""
    from scipy.ndimage import uniform_filter

    for size in (1, 3, 5, 9, 17, 33, 65):
        if size == 1:
            img, cnt = image, counts
        else:
            img = uniform_filter(image, size, mode="constant")
            cnt = uniform_filter(counts.astype(np.float64), size, mode="constant") * size * size
        k = int(np.argmax(img))
        if cnt.flat[k] >= MIN_RAYS_PER_PEAK or size == 65:
            return float(img.flat[k])
    return float(image.max())  # pragma: no cover - the loop always returns


def _focus(p: np.ndarray, d: np.ndarray, w: np.ndarray) -> float | None:
    """Axial distance from the detector plane to the bundle's least-squares waist (+ behind it)."""
    s = d[:, :2] / d[:, 2:3]  # transverse slopes: a ray is at p + Δz · s after Δz more along the axis
    ds = s - np.average(s, axis=0, weights=w)
    dp = p[:, :2] - np.average(p[:, :2], axis=0, weights=w)
    spread = float(np.sum(w * np.einsum("ij,ij->i", ds, ds)))
    scale = float(np.sum(w * np.einsum("ij,ij->i", dp, dp)))
    if spread <= 1e-18 * max(scale, 1e-300):
        return None  # collimated: no focus
    dz = -float(np.sum(w * np.einsum("ij,ij->i", dp, ds))) / spread
    return dz if math.isfinite(dz) else None


__all__ = ["GhostPair", "GhostReport", "ghost_report"]
