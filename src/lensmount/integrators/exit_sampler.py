"""Backward directions from a detector point toward the last lens (stage 1's first step).

From detector point x the light that can arrive comes mostly through the last
optical surface (a cone of a few degrees at f/7), the rest from the housing. We draw
ω from a mixture: with probability c through a uniform point q on the disc D
(radius R_D, area A_D, normal to the axis at z_D, covering the last surface as seen
from the detector), otherwise cosine-weighted over the hemisphere facing the lens.
The estimator of E = ∫ L cos θ dω is w · L(ω) with

    w = cos θ / p(ω),   p(ω) = c |q − x|² / (A_D cos θ_q) · [ω crosses D] + (1 − c) cos θ / π

Both D and the detector are normal to the axis, so cos θ_q = cos θ. The hemisphere
part keeps it unbiased whatever lies outside D; D only moves samples where light is,
so doubling D or changing c leaves the expectation unchanged (tested).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ExitDisc:
    """Disc normal to the axis at z (mm), centred on the axis, radius (mm).

    facing : −1 when the lens lies toward −z from the detector (the usual case), +1 otherwise.
    """

    z: float
    radius: float
    facing: float = -1.0

    @property
    def area(self) -> float:
        return math.pi * self.radius**2


def mixture_pdf(x: np.ndarray, omega: np.ndarray, disc: ExitDisc, c: float) -> np.ndarray:
    """(N,) solid-angle pdf of the mixture at directions omega (N,3) from points x (N,3)."""
    cos = omega[:, 2] * disc.facing
    ok = cos > 0
    cos_safe = np.where(ok, cos, 1.0)
    t = (disc.z - x[:, 2]) / np.where(ok, omega[:, 2], 1.0)
    q = x + t[:, None] * omega
    inside = ok & (t > 0) & (q[:, 0] ** 2 + q[:, 1] ** 2 <= disc.radius**2)
    p_disc = np.where(inside, t * t / (disc.area * cos_safe), 0.0)  # |q − x| = t for a unit ω
    p_hemi = np.where(ok, cos_safe / math.pi, 0.0)
    return c * p_disc + (1.0 - c) * p_hemi


def sample_toward_exit(x: np.ndarray, u: np.ndarray, disc: ExitDisc, c: float = 0.9):
    """Directions from detector points toward the optics, and their weights.

    x : (N, 3) points on the detector; u : (N, 3) uniform numbers in [0, 1).
    Returns (omega (N, 3) unit, weight (N,) = cos θ / p(ω)); weight 0 where cos θ ≤ 0.
    """
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    if not 0.0 <= c <= 1.0:
        raise ValueError(f"mixture weight c must lie in [0, 1], got {c}")
    use_disc = u[:, 0] < c
    # Disc strategy: q uniform on D.
    rq = disc.radius * np.sqrt(u[:, 1])
    phi = 2.0 * math.pi * u[:, 2]
    q = np.stack([rq * np.cos(phi), rq * np.sin(phi), np.full(n, disc.z)], axis=1)
    to_q = q - x
    to_q /= np.maximum(np.linalg.norm(to_q, axis=1, keepdims=True), 1e-300)
    # Hemisphere strategy: cosine-weighted about the facing axis.
    sin_t = np.sqrt(u[:, 1])
    cos_t = np.sqrt(np.maximum(1.0 - u[:, 1], 0.0))
    hemi = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), disc.facing * cos_t], axis=1)
    omega = np.where(use_disc[:, None], to_q, hemi)
    pdf = mixture_pdf(x, omega, disc, c)
    cos = omega[:, 2] * disc.facing
    good = (cos > 0) & (pdf > 0)
    weight = np.where(good, np.where(good, cos, 0.0) / np.where(good, pdf, 1.0), 0.0)
    return omega, weight


__all__ = ["ExitDisc", "mixture_pdf", "sample_toward_exit"]
