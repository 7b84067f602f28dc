"""A density estimate on a line, with the gather's bookkeeping and nothing else: for the bias ladder's tests.

A face is the segment [face_lo, face_hi]. Photons land on it from a mixture of lit regions (uniform
segments), each with flux Φ = total / N; hit points are the detector's view of it: a seen window
[seen_lo, seen_hi] sampled uniformly (a Poisson number of them), each with weight τ = I · window / H.
A hit point at y gathers, at radius ρ, Σ Φ_p [|x_p − y| < ρ] / |[y − ρ, y + ρ] ∩ face| (the on-face
length, as `FaceBoundaries` gives the on-face area). The truth is ∫ L I exactly: L is the lit regions'
flux per length, I the window's indicator times its importance.

Every mechanism of the kernel bias the review named is a choice of lit regions, window and radius: a
lit spot far narrower than the radius inside a narrow window (the estimate diluted, F ∝ 1/ρ), light
and window meeting at an edge (first order in ρ), a dome of light (second order), both at once with
opposite signs, and the progressive schedule's early passes (s_1 = 1, wide) against later ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.integrators.estimate import PassEstimate
from lensmount.integrators.photon_mapping.photon_gather import BIAS_LADDER
from lensmount.integrators.photon_mapping.radius import radius_scale


@dataclass
class LineScene:
    """lit : ((lo, hi, flux), ...) uniform lit segments; dome : (centre, half width, flux) a lit region
    of profile 1 − ((x − centre)/half width)² (second-order bias of opposite sign to an edge's);
    seen : (lo, hi) the window the detector sees, importance 1; radius : r_0; face : (lo, hi)."""

    lit: tuple
    seen: tuple
    radius: float
    face: tuple = (-100.0, 100.0)
    dome: tuple | None = None
    hits: float = 400.0  # mean number of hit points per pass
    photons: int = 4000
    schedule_alpha: float = 0.7

    def truth(self) -> float:
        lo, hi = self.seen
        total = sum(f * max(0.0, min(b, hi) - max(a, lo)) / (b - a) for a, b, f in self.lit)
        if self.dome is not None:
            c, w, f = self.dome
            xs = np.linspace(max(lo, c - w), min(hi, c + w), 200_001)
            if len(xs) and xs[-1] > xs[0]:
                total += float(np.trapezoid(f * (1 - ((xs - c) / w) ** 2) * 0.75 / w, xs))
        return total

    def _photons(self, rng) -> tuple[np.ndarray, float]:
        regions = [(a, b, f) for a, b, f in self.lit]
        flux = np.array([f for _, _, f in regions] + ([self.dome[2]] if self.dome else []), float)
        total = float(flux.sum())
        which = rng.choice(len(flux), size=self.photons, p=flux / total)
        x = np.empty(self.photons)
        for k, (a, b, _) in enumerate(regions):
            m = which == k
            x[m] = rng.uniform(a, b, m.sum())
        if self.dome is not None:
            c, w, _ = self.dome
            m = which == len(regions)
            u = rng.uniform(-1, 1, (m.sum() * 3 + 10, 2))  # rejection: density ∝ 1 − t²
            t = u[u[:, 1] * 0.5 + 0.5 < 1 - u[:, 0] ** 2, 0][: m.sum()]
            x[m] = c + w * t
        return np.sort(x), total / self.photons

    def pass_estimate(self, pass_index: int, seed: int) -> PassEstimate:
        """One pass: its flux at r_0 · s_i and on the ladder, as `Bidirectional.run_pass` reports them."""
        rng = np.random.default_rng([seed, pass_index])
        x, phi = self._photons(rng)
        lo, hi = self.seen
        h = rng.poisson(self.hits)
        y = rng.uniform(lo, hi, h)
        tau = (hi - lo) / self.hits  # Σ τ over the window's Poisson hits estimates its length
        r = self.radius * radius_scale(pass_index, self.schedule_alpha)
        rungs = []
        for m in BIAS_LADDER:
            rho = m * r
            count = np.searchsorted(x, y + rho) - np.searchsorted(x, y - rho)
            length = np.minimum(y + rho, self.face[1]) - np.maximum(y - rho, self.face[0])
            rungs.append(float(np.sum(tau * phi * count / length)))
        img = np.array([[rungs[0]]])
        return PassEstimate(img, img[None], ["face"], 1.0, self.photons, radius_scale=r / self.radius,
                            part_flux_ladder=np.array(rungs)[:, None])
