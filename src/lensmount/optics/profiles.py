"""Surface profiles: sag, normal and ray intersection, vectorised, float64.

One `Profile` per optical surface in its local frame: vertex at the origin, axis +z.
The same code serves the sequential real-ray trace and the non-sequential tracer's
analytic refinement, so both agree to rounding.

    sag(r) = c r^2 / (1 + sqrt(1 - (1+k) c^2 r^2)) + sum_i A_(2i+4) r^(2i+4) [+ a Q-type departure]

A Forbes Q-type face (lensmount.optics.qtype) adds its departure to the same base conic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.optics.qtype import QType

_NEWTON_STEPS = 30
_NEWTON_TOL = 1e-12  # mm


@dataclass(frozen=True)
class Profile:
    """Rotationally symmetric surface: curvature c (1/mm), conic k, even-asphere terms, a Q-type departure.

    Array arguments are shaped (n,) for radii and (n, 3) for points/directions.
    """

    curvature: float = 0.0
    conic: float = 0.0
    aspheric: tuple[float, ...] = ()
    qtype: QType | None = None

    @classmethod
    def of(cls, surface) -> "Profile":
        return cls(surface.curvature, surface.conic, tuple(surface.aspheric), surface.qtype)

    @property
    def is_plane(self) -> bool:
        return self.curvature == 0.0 and self.is_conic

    @property
    def vertex_curvature(self) -> float:
        """The paraxial curvature (1/mm): the base's plus what a Q-type departure adds at the vertex."""
        return self.curvature + (0.0 if self.qtype is None else self.qtype.vertex_curvature)

    @property
    def is_conic(self) -> bool:
        """No polynomial departure: the ray crossing is a quadratic's root (else Newton finds it)."""
        return not any(self.aspheric) and self.qtype is None

    def max_radius(self) -> float:
        """Largest r where the conic part is defined (inf for planes and hyperboloids)."""
        q = (1.0 + self.conic) * self.curvature**2
        return np.inf if q <= 0 else 1.0 / np.sqrt(q)

    def sag(self, r2: np.ndarray) -> np.ndarray:
        """Sag z at squared radius r2; NaN-free: beyond the conic's edge it returns inf."""
        r2 = np.asarray(r2, dtype=np.float64)
        c, k = self.curvature, self.conic
        arg = 1.0 - (1.0 + k) * c * c * r2
        ok = arg >= 0.0
        z = np.where(ok, c * r2 / (1.0 + np.sqrt(np.where(ok, arg, 1.0))), np.inf)
        rn = r2 * r2
        for a in self.aspheric:
            z = z + a * rn
            rn = rn * r2
        if self.qtype is not None:
            z = z + self.qtype.departure(r2, c, k)[0]
        return z

    def slope(self, r2: np.ndarray) -> np.ndarray:
        """dz/dr divided by r (finite at r = 0)."""
        r2 = np.asarray(r2, dtype=np.float64)
        c, k = self.curvature, self.conic
        arg = np.maximum(1.0 - (1.0 + k) * c * c * r2, 1e-300)
        g = c / np.sqrt(arg)
        rn = r2
        for i, a in enumerate(self.aspheric):
            g = g + (2 * i + 4) * a * rn
            rn = rn * r2
        if self.qtype is not None:
            g = g + self.qtype.departure(r2, c, k)[1]
        return g

    def normal(self, p: np.ndarray) -> np.ndarray:
        """Unit normal at points p (n, 3) on the surface, oriented toward +z."""
        p = np.asarray(p, dtype=np.float64)
        g = self.slope(p[:, 0] ** 2 + p[:, 1] ** 2)
        n = np.stack([-g * p[:, 0], -g * p[:, 1], np.ones(len(p))], axis=1)
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    def intersect(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Ray parameter t of the hit with the sheet through the vertex.

        o, d: (n, 3) origins and unit directions in the local frame. Returns t (n,),
        `inf` where the ray misses (no real root, or the root lies on the far sheet
        of a sphere/conic). Negative t means the surface is behind the origin.
        """
        o = np.asarray(o, dtype=np.float64)
        d = np.asarray(d, dtype=np.float64)
        t = self._intersect_conic(o, d)
        if not self.is_conic:
            t = self._newton(o, d, np.where(np.isfinite(t), t, -o[:, 2] / _safe(d[:, 2])))
        return t

    def _intersect_conic(self, o, d):
        c, k1 = self.curvature, 1.0 + self.conic
        a = c * (d[:, 0] ** 2 + d[:, 1] ** 2 + k1 * d[:, 2] ** 2)
        b = c * (o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1] + k1 * o[:, 2] * d[:, 2]) - d[:, 2]
        cc = c * (o[:, 0] ** 2 + o[:, 1] ** 2 + k1 * o[:, 2] ** 2) - 2.0 * o[:, 2]
        disc = b * b - a * cc
        ok = disc >= 0.0
        root = np.sqrt(np.where(ok, disc, 0.0))
        # -C / (B + sign(B) sqrt(disc)) and (B + sign(B) sqrt(disc)) / -A are the two roots without
        # cancellation (the first stays exact as c -> 0). Travelling +z the hit is the first one if
        # it lies on the vertex sheet, else the second: a ray that starts inside the sphere of a
        # surface concave toward it, or beyond its centre (an object or a previous surface farther
        # than |R|), meets the far sheet through the first root and the vertex sheet through the
        # second. Travelling -z
        # (after a mirror) it is the root on the vertex sheet nearest the vertex plane: a
        # hyperboloid's vertex sheet is met through the second root there (a Cassegrain
        # secondary), and a ray can cross a paraboloid twice.
        den = b + np.where(b >= 0.0, root, -root)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = np.where(ok & (den != 0.0), -cc / np.where(den != 0.0, den, 1.0), np.inf)
            t2 = np.where(ok & (a != 0.0), -den / np.where(a != 0.0, a, 1.0), np.inf)
        t0 = -o[:, 2] / _safe(d[:, 2])

        def valid(t):
            z = o[:, 2] + np.where(np.isfinite(t), t, 0.0) * d[:, 2]
            return np.isfinite(t) & (k1 * c * z <= 1.0 + 1e-12)

        v1, v2 = valid(t1), valid(t2)
        take2 = v2 & (~v1 | ((d[:, 2] < 0.0) & (np.abs(t2 - t0) < np.abs(t1 - t0))))
        return np.where(take2, t2, np.where(v1, t1, np.inf))

    def _newton(self, o, d, t):
        t = t.copy()
        live = np.isfinite(t)
        for _ in range(_NEWTON_STEPS):
            if not live.any():
                break
            p = o[live] + t[live, None] * d[live]
            r2 = p[:, 0] ** 2 + p[:, 1] ** 2
            f = p[:, 2] - self.sag(r2)
            g = self.slope(r2)
            df = d[live, 2] - g * (p[:, 0] * d[live, 0] + p[:, 1] * d[live, 1])
            with np.errstate(invalid="ignore"):  # beyond a Q-type's reach f and df are both inf: masked
                step = np.where(np.isfinite(f) & (np.abs(df) > 1e-15), f / _safe(df), np.inf)
            idx = np.flatnonzero(live)
            t[idx] = t[idx] - step
            done = np.abs(step) < _NEWTON_TOL
            bad = ~np.isfinite(t[idx])
            t[idx[bad]] = np.inf
            live[idx[done | bad]] = False
        t[live] = np.inf  # did not converge: treat as a miss rather than return a wrong point
        return t


def _safe(x):
    return np.where(np.abs(x) > 1e-300, x, 1e-300)
