"""Ghost analysis: every ghost route between optical surfaces, traced deterministically, ranked.

The routes come from `trace.ghosts` (real rays, the real Fresnel or coating reflectance and
transmittance per wavelength at every crossing; with the scene's tracer the mount vignettes them
as it vignettes photons): the two-reflection ghosts (i, j), and with ghost order 3 the
four-reflection ones too. A report per route costs one sequential trace instead of the millions of
photons a stochastic reflection branch spends to find the same light, and is the same on every run.

Per route: flux on the detector (as a fraction of the flux entering the entrance pupil, the
`stray_fraction` of a simulation), its share of all ghost flux, the peak irradiance E/E_sun (pixel
counts smoothed until the estimate holds ≥ 25 rays, so a defocused ghost's peak is not one ray's
noise), the footprint (centroid and the radius holding 90 % of the flux), and the distance of the
ghost's best focus from the detector plane (least-squares waist of the bundle; positive behind the
detector, None for a collimated ghost). Ranked by peak irradiance: the ghost that makes a visible
spot first. Pairs where a surface cannot reflect (perfect AR, R = 0, a dummy surface such as the
stop plane) are listed as skipped; no ray is traced for them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lensmount.errors import InputError
from lensmount.trace.ghosts import CENTRED, Walls, launch, reflecting, reflections_of_order, trace_routes

RAYS_ACROSS = 151  # lattice points across the first clear aperture
MIN_RAYS_PER_PEAK = 25


@dataclass
class GhostPair:
    """One ghost route. surfaces: 1-based surface numbers where it reflects, in order ((j, i) for the
    two-reflection ghost of surfaces i < j); first, second: the lowest and highest of them."""

    surfaces: tuple[int, ...]
    fraction: float  # detector flux / flux entering the entrance pupil
    share: float  # of all ghost flux on the detector
    peak_irradiance: float  # E / E_sun
    focus_from_detector_mm: float | None
    centroid_mm: tuple[float, float]
    radius90_mm: float
    image: np.ndarray = field(repr=False)  # (ny, nx) E / E_sun

    @property
    def first(self) -> int:
        return min(self.surfaces)

    @property
    def second(self) -> int:
        return max(self.surfaces)

    @property
    def _ordered(self) -> tuple[int, ...]:
        """A pair in surface order (i, j); a longer route in the order the light meets its reflections."""
        return tuple(sorted(self.surfaces)) if len(self.surfaces) == 2 else self.surfaces

    @property
    def label(self) -> str:
        return ("–" if len(self.surfaces) == 2 else "→").join(str(k) for k in self._ordered)

    @property
    def slug(self) -> str:
        """For file and channel names: s1-s6."""
        return "-".join(f"s{k}" for k in self._ordered)

    def to_dict(self) -> dict:
        return {"surfaces": list(self._ordered),
                "reflections": len(self.surfaces), "fraction": self.fraction, "share": self.share,
                "peak_irradiance": self.peak_irradiance, "focus_from_detector_mm": self.focus_from_detector_mm,
                "centroid_mm": list(self.centroid_mm), "radius90_mm": self.radius90_mm}


@dataclass
class GhostReport:
    pairs: list[GhostPair]  # ranked by peak irradiance, strongest first
    skipped: list[tuple[int, int]]  # pairs with no reflectance (perfect AR)
    total_fraction: float
    rays_per_pair: int
    order: int = 2

    def to_dict(self) -> dict:
        return {"pairs": [p.to_dict() for p in self.pairs], "skipped_no_reflectance": [list(s) for s in self.skipped],
                "total_fraction": self.total_fraction, "rays_per_pair": self.rays_per_pair, "order": self.order,
                "ranked_by": "peak_irradiance"}


def ghost_report(scene, tracer=None, rays_across: int = RAYS_ACROSS, order: int = 2) -> GhostReport:
    """Trace every ghost route of `scene` up to `order` (2: two reflections; 3: four too) and rank them.

    tracer : the scene's `Tracer`, whose mesh blocks ghost light where the mount's walls do;
        None traces the prescription alone (clear apertures only).
    """
    if not scene.source.at_infinity:
        raise InputError("the ghost analysis launches a collimated beam from a source at infinity; this scene's "
                         "source is at a finite distance", field="source.type",
                         valid="a scene whose source is type = 'sun' or 'collimated'")
    surfaces = sorted(scene.optical, key=lambda s: s.index)
    d0 = np.asarray(scene.source.direction, np.float64)
    aperture = scene.entrance_pupil_area_mm2 * scene.source.entering_fraction
    reflects = reflecting(scene)
    numbers = [s.index + 1 for s in surfaces]
    skipped = [(numbers[a], numbers[b]) for b in range(len(surfaces)) for a in range(b)
               if not (reflects[a] and reflects[b])]
    if d0[2] <= 0.0 or aperture <= 0.0 or reflects.sum() < 2:  # no light enters, or nothing to reflect twice
        return GhostReport([], skipped, 0.0, 0, order)
    walls = None if tracer is None else Walls(tracer)
    rays = launch(scene, rays_across, CENTRED, walls)
    response = scene.detector.spectral_weight
    pairs = [_pair(a.route, a.points, a.directions,
                   a.flux if response is None else a.flux * np.asarray(response, np.float64)[a.wavelength],
                   scene.detector, aperture)
             for a in trace_routes(scene, rays, reflections_of_order(order), walls)]
    pairs = [g for g in pairs if g.fraction > 0]
    total = sum(g.fraction for g in pairs)
    for g in pairs:
        g.share = g.fraction / total if total > 0 else 0.0
    pairs.sort(key=lambda g: g.peak_irradiance, reverse=True)
    return GhostReport(pairs, skipped, total, rays.positions * len(scene.wavelengths_um), order)


def _pair(route: tuple[int, ...], p, d, w, det, aperture: float) -> GhostPair:
    pix = det.pixel_of(p)
    on = (pix >= 0) & (w > 0)
    image = np.bincount(pix[on], weights=w[on], minlength=det.nx * det.ny).reshape(det.ny, det.nx) / det.pixel_area
    flux = float(w[on].sum())
    if flux <= 0.0:
        return GhostPair(route, 0.0, 0.0, 0.0, None, (0.0, 0.0), 0.0, image)
    counts = np.bincount(pix[on], minlength=det.nx * det.ny).reshape(det.ny, det.nx)
    peak = _peak(image, counts)
    x, y, wt = p[on, 0], p[on, 1], w[on]
    cx, cy = float(np.average(x, weights=wt)), float(np.average(y, weights=wt))
    r = np.hypot(x - cx, y - cy)
    order = np.argsort(r)
    r90 = float(r[order][np.searchsorted(np.cumsum(wt[order]), 0.9 * flux)].item()) if len(r) else 0.0
    return GhostPair(route, flux / aperture, 0.0, peak, _focus(p[on], d[on], wt), (cx, cy), r90, image)


def _peak(image: np.ndarray, counts: np.ndarray) -> float:
    """Largest irradiance after smoothing with the smallest box that holds ≥ MIN_RAYS_PER_PEAK rays at the peak."""
    from scipy.ndimage import uniform_filter  # lazy: keeps lensmount --help from loading scipy.ndimage

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
