"""The ray from a scatter in front of the optics to a point behind them, through the glass between.

Why. Past the field most stray light scatters on a mechanical face y1 in front of (or between) lens
groups, refracts through the optics behind it and lands on a face y2 the detector sees straight; a
photon makes that y1 → y2 step rarely (the strip by the detector subtends a tiny solid angle through
the rear group), so a few photons carry a pass. Manifold next-event estimation (Hanika, Droske &
Fascione 2015) connects y1 to a chosen y2 instead: the specular chain between two points is found by
a root find, and the connection carries the chain's generalised geometric term.

What. In a coaxial system the chain's ray is fixed by where it crosses the plane of the first
surface's vertex, a point a = (a_x, a_y): the direction at y1 is a − y1. Tracing that ray through the
surfaces between (Snell's law on each analytic profile, the media's indices at the photon's
wavelength) and on to the plane z = y2_z gives a landing point X(a); the chain from y1 to y2 is the
root of X(a) − y2_xy, found by Newton's method with a central finite-difference Jacobian J = ∂X/∂a,
every photon at once. At the root

    |dω1/dA2| = (|ω1_z| / |a − y1|²) / |det J| · |d2 · n2| / |d2_z|

(solid angle at y1 per area of the aim plane, over the aim plane's area per landing plane's area,
times the landing plane's area per area of y2's face; d2 the chain's last direction, n2 the face's
normal). Without glass this is cos θ2 / |y1 − y2|², the ordinary geometric term's. Rays that leave a
surface's mechanical aperture, meet total internal reflection or do not converge are refused: the
found chain is a candidate whose visibility (metal on the way) and Fresnel / absorption throughput
the tracer decides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.optics.snell import refract

NEWTON_STEPS = 25
NEWTON_TOL = 1e-7  # mm on the landing plane
FD_STEP = 1e-5  # mm on the aim plane: the Jacobian's central differences


@dataclass(frozen=True)
class Chain:
    """The optical surfaces a ray crosses from z_from to z_to along +z, in order (scene.optical entries)."""

    surfaces: tuple

    @classmethod
    def between(cls, optical, z_from: float, z_to: float) -> "Chain":
        inside = [s for s in optical if z_from < s.z_vertex < z_to and not s.mirror]
        return cls(tuple(sorted(inside, key=lambda s: s.z_vertex)))

    @property
    def aim_z(self) -> float:
        return float(self.surfaces[0].z_vertex)


@dataclass
class ChainRays:
    """The solved chains of M connections.

    direction : (M, 3) unit direction at y1 toward the first surface
    exit_direction : (M, 3) unit direction after the last surface (toward y2)
    d_omega_d_area : (M,) |dω1/dA2| (1/mm²) per area of y2's face
    ok : (M,) converged, inside every surface's aperture, no total internal reflection, y2 ahead
    """

    direction: np.ndarray
    exit_direction: np.ndarray
    d_omega_d_area: np.ndarray
    ok: np.ndarray


def trace_chain(chain: Chain, origin: np.ndarray, direction: np.ndarray, wl: np.ndarray):
    """Trace rays (M,) from `origin` along `direction` through the chain's surfaces at wavelength index
    wl: (last point (M, 3), last direction (M, 3), passed (M,) bool: every surface met inside its
    mechanical aperture and no total internal reflection)."""
    p, d = origin.astype(np.float64).copy(), direction.astype(np.float64).copy()
    ok = np.ones(len(p), bool)
    for s in chain.surfaces:
        local = p - np.array([0.0, 0.0, s.z_vertex])
        t = s.profile.intersect(local, d)
        hit = np.isfinite(t) & (t > 0)
        t = np.where(hit, t, 0.0)
        q = local + t[:, None] * d
        rim = s.mechanical_semi_diameter if np.isfinite(s.mechanical_semi_diameter) else s.clear_semi_diameter
        hit &= (q[:, 0] ** 2 + q[:, 1] ** 2) <= rim * rim
        new_d, tir, _, _ = refract(d, s.profile.normal(q), s.n_before[wl] / s.n_after[wl])
        ok &= hit & ~tir
        p = np.where(ok[:, None], q + np.array([0.0, 0.0, s.z_vertex]), p)
        d = np.where(ok[:, None], new_d, d)
    return p, d, ok


def _landing(chain: Chain, y1: np.ndarray, aim: np.ndarray, z2: np.ndarray, wl: np.ndarray):
    """(M, 2) where the chain's ray through aim point `aim` (M, 2) crosses the plane z2, the ray's last
    direction, its direction at y1, and whether it got there."""
    to_a = np.column_stack([aim, np.full(len(aim), chain.aim_z)]) - y1
    w1 = to_a / np.linalg.norm(to_a, axis=1)[:, None]
    p, d, ok = trace_chain(chain, y1, w1, wl)
    ahead = d[:, 2] > 1e-9
    t = np.where(ahead, (z2 - p[:, 2]) / np.where(ahead, d[:, 2], 1.0), 0.0)
    ok &= ahead & (t >= 0)
    return p[:, :2] + t[:, None] * d[:, :2], d, w1, ok


def solve_chain(chain: Chain, y1: np.ndarray, y2: np.ndarray, normal2: np.ndarray, wl: np.ndarray,
                start: np.ndarray | None = None) -> ChainRays:
    """The chain's rays from points y1 (M, 3) to points y2 (M, 3) on faces of normal normal2 (M, 3),
    at wavelength index wl (M,) (module docstring). start (M, 2): the first guess on the aim plane
    (default: where the straight line y1 → y2 crosses it)."""
    m = len(y1)
    z2 = y2[:, 2]
    if start is None:
        s = (chain.aim_z - y1[:, 2]) / np.where(np.abs(y2[:, 2] - y1[:, 2]) > 1e-12, y2[:, 2] - y1[:, 2], 1e-12)
        start = y1[:, :2] + s[:, None] * (y2[:, :2] - y1[:, :2])
    a = start.astype(np.float64).copy()
    live = np.ones(m, bool)
    done = np.zeros(m, bool)
    for _ in range(NEWTON_STEPS):
        rows = np.flatnonzero(live & ~done)
        if not len(rows):
            break
        x, _, _, ok = _landing(chain, y1[rows], a[rows], z2[rows], wl[rows])
        r = x - y2[rows, :2]
        done[rows[ok & (np.hypot(r[:, 0], r[:, 1]) < NEWTON_TOL)]] = True
        jac, jok = _jacobian(chain, y1[rows], a[rows], z2[rows], wl[rows])
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        good = ok & jok & (np.abs(det) > 1e-300) & ~done[rows]
        live[rows[~ok | ~jok | (np.abs(det) <= 1e-300)]] = False
        g = np.flatnonzero(good)
        inv = np.stack([np.stack([jac[g, 1, 1], -jac[g, 0, 1]], -1), np.stack([-jac[g, 1, 0], jac[g, 0, 0]], -1)], 1)
        step = np.einsum("nij,nj->ni", inv, r[g]) / det[g][:, None]
        a[rows[g]] -= _limited(step, chain)
    ok = done & live
    x, d2, w1, reached = _landing(chain, y1, a, z2, wl)
    jac, jok = _jacobian(chain, y1, a, z2, wl)
    ok &= reached & jok
    det = np.abs(jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0])
    to_a = np.column_stack([a, np.full(m, chain.aim_z)]) - y1
    per_aim = np.abs(w1[:, 2]) / np.einsum("ij,ij->i", to_a, to_a)
    per_face = np.abs(np.einsum("ij,ij->i", d2, normal2)) / np.maximum(np.abs(d2[:, 2]), 1e-300)
    ok &= det > 0
    g = np.where(ok, per_aim / np.where(ok, det, 1.0) * per_face, 0.0)
    return ChainRays(w1, d2, g, ok)


def _jacobian(chain, y1, a, z2, wl):
    """(M, 2, 2) ∂X/∂a by central differences, and where all four neighbours landed."""
    jac = np.zeros((len(a), 2, 2))
    ok = np.ones(len(a), bool)
    for k in range(2):
        e = np.zeros(2)
        e[k] = FD_STEP
        xp, _, _, okp = _landing(chain, y1, a + e, z2, wl)
        xm, _, _, okm = _landing(chain, y1, a - e, z2, wl)
        jac[:, :, k] = (xp - xm) / (2 * FD_STEP)
        ok &= okp & okm
    return jac, ok


def _limited(step: np.ndarray, chain: Chain) -> np.ndarray:
    """Newton steps no longer than a fifth of the first surface's aperture (keeps the aim on the glass)."""
    s = chain.surfaces[0]
    cap = 0.2 * (s.mechanical_semi_diameter if np.isfinite(s.mechanical_semi_diameter) else s.clear_semi_diameter)
    n = np.linalg.norm(step, axis=1)
    return step * np.minimum(1.0, cap / np.maximum(n, 1e-300))[:, None]


__all__ = ["Chain", "ChainRays", "solve_chain", "trace_chain"]
