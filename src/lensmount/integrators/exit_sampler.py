"""Backward directions from a detector point toward the optics (stage 1's first step).

From detector point x the light that can arrive comes mostly through the last
optical surface (a cone of a few degrees at f/7), the rest from the housing. We draw
ω from a mixture: with probability c_k through a uniform point q on target k — the
disc D covering the last optical surface, and optionally a thin annulus around the
exit pupil's rim (the stop edge seen through the rear optics, where the 50 µm
diaphragm edge lies) or the pilot-learned band there (`targets.LearnedRim`, whose
density depends on x and the wavelength) — otherwise cosine-weighted over the
hemisphere facing the lens. The estimator of E = ∫ L cos θ dω is w · L(ω) with

    w = cos θ / p(ω),   p(ω) = Σ_k c_k p_k(q_k | x, λ) |q_k − x|² / cos θ_q
                               + (1 − Σ c_k) cos θ / π

p_k the target's density per unit area at the point q_k where ω crosses its plane
(1/A_k on a uniform disc or annulus, 0 outside).

Targets and detector are normal to the axis, so cos θ_q = cos θ. The hemisphere part
keeps it unbiased whatever lies outside the targets; the targets only move samples
where light is, so doubling D or changing the c_k leaves the expectation unchanged (tested).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ExitDisc:
    """Disc (or annulus, r_inner > 0) normal to the axis at z (mm), centred on the axis.

    facing : −1 when the lens lies toward −z from the detector (the usual case), +1 otherwise.
    """

    z: float
    radius: float
    facing: float = -1.0
    r_inner: float = 0.0

    @property
    def area(self) -> float:
        return math.pi * (self.radius**2 - self.r_inner**2)

    def area_pdf(self, x: np.ndarray, q: np.ndarray, wavelength: np.ndarray | None = None) -> np.ndarray:
        """(N,) density per unit area of the target's points q (N,3) on its plane (x unused: uniform)."""
        r2 = q[:, 0] ** 2 + q[:, 1] ** 2
        return np.where((r2 <= self.radius**2) & (r2 >= self.r_inner**2), 1.0 / self.area, 0.0)

    def sample_points(self, x: np.ndarray, u: np.ndarray, wavelength: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) points uniform in area on the disc / annulus; u (N, 2) uniform numbers."""
        rq = np.sqrt(self.r_inner**2 + u[:, 0] * (self.radius**2 - self.r_inner**2))
        phi = 2.0 * math.pi * u[:, 1]
        return np.stack([rq * np.cos(phi), rq * np.sin(phi), np.full(len(u), self.z)], axis=1)


def mixture_pdf(x: np.ndarray, omega: np.ndarray, targets, weights, wavelength: np.ndarray | None = None) -> np.ndarray:
    """(N,) solid-angle pdf at directions omega (N,3) from points x (N,3); facing from targets[0].

    A target is anything with `z`, `area_pdf(x, q, wavelength)` and `sample_points(x, u, wavelength)`
    (ExitDisc; `targets.LearnedRim`, whose density depends on x and on the wavelength index (N,)).
    Every target's density is evaluated for every ω, whichever target drew it: that keeps w exact.
    """
    targets, weights = _as_lists(targets, weights)
    facing = targets[0].facing
    cos = omega[:, 2] * facing
    ok = cos > 0
    cos_safe = np.where(ok, cos, 1.0)
    pdf = (1.0 - sum(weights)) * np.where(ok, cos_safe / math.pi, 0.0)
    for tgt, c in zip(targets, weights):
        if c <= 0:
            continue
        t = (tgt.z - x[:, 2]) / np.where(ok, omega[:, 2], 1.0)
        q = x + t[:, None] * omega
        inside = ok & (t > 0)
        dens = np.where(inside, tgt.area_pdf(x, q, wavelength), 0.0)
        pdf = pdf + c * np.where(inside, dens * t * t / cos_safe, 0.0)  # |q − x| = t for a unit ω
    return pdf


def _as_lists(targets, weights):
    if isinstance(targets, ExitDisc):
        return [targets], [float(weights)]
    return list(targets), [float(c) for c in weights]


def sample_toward_exit(x: np.ndarray, u: np.ndarray, targets, weights=0.9, wavelength: np.ndarray | None = None):
    """Directions from detector points toward the optics, and their weights.

    x : (N, 3) points on the detector; u : (N, 3) uniform numbers in [0, 1).
    targets : an ExitDisc (or any target, see `mixture_pdf`) or a list of them;
    weights : their probabilities c_k (sum ≤ 1); wavelength : (N,) index, for targets that use it.
    Returns (omega (N, 3) unit, weight (N,) = cos θ / p(ω)); weight 0 where cos θ ≤ 0.
    """
    targets, weights = _as_lists(targets, weights)
    x = np.asarray(x, dtype=np.float64)
    if any(c < 0 for c in weights) or sum(weights) > 1.0 + 1e-12:
        raise ValueError(f"mixture weights must be ≥ 0 with sum ≤ 1, got {weights}")
    facing = targets[0].facing
    phi = 2.0 * math.pi * u[:, 2]
    # Hemisphere strategy (default): cosine-weighted about the facing axis.
    sin_t = np.sqrt(u[:, 1])
    cos_t = np.sqrt(np.maximum(1.0 - u[:, 1], 0.0))
    omega = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), facing * cos_t], axis=1)
    edge = 0.0
    for tgt, c in zip(targets, weights):
        use = (u[:, 0] >= edge) & (u[:, 0] < edge + c)
        edge += c
        if not use.any():
            continue
        wl = None if wavelength is None else np.asarray(wavelength)[use]
        q = tgt.sample_points(x[use], u[use, 1:3], wl)
        to_q = q - x[use]
        omega[use] = to_q / np.maximum(np.linalg.norm(to_q, axis=1, keepdims=True), 1e-300)
    pdf = mixture_pdf(x, omega, targets, weights, wavelength)
    cos = omega[:, 2] * facing
    good = (cos > 0) & (pdf > 0)
    weight = np.where(good, np.where(good, cos, 0.0) / np.where(good, pdf, 1.0), 0.0)
    return omega, weight


__all__ = ["ExitDisc", "mixture_pdf", "sample_toward_exit"]
