"""Forbes Q-type aspheres: the departure of a surface from its base, as orthogonal polynomials.

Two forms (G. W. Forbes, "Shape specification for axially symmetric optical surfaces", Opt. Express
15, 5218 (2007)), with u = r / r_n (r_n the normalisation radius) and x = u²:

    Qcon:  z = c r² / (1 + sqrt(1 - (1+k) c² r²))  +  u⁴ Σ a_m Q^con_m(x)
    Qbfs:  z = c r² / (1 + sqrt(1 - (1+k) c² r²))  +  φ(r) u² (1 - u²) Σ a_m Q^bfs_m(x),
           φ = sqrt((1 - k c² r²) / (1 - (1+k) c² r²))

Q^con_m(x) = P_m^(0,4)(2x - 1), a Jacobi polynomial (orthogonal in sag). Q^bfs_m are orthonormal in
slope; the departure they sum is measured along the base's normal, which φ projects onto the axis:
Forbes's 2007 form has a sphere for base (k = 0, φ = 1/sqrt(1 - c² r²)); his generalisation to a
conic base ("Manufacturability estimates for optical aspheres", Opt. Express 19, 9923 (2011)) is the
φ above, and OpticStudio's Q-type surface carries a conic on a Qbfs face too. Evidence for both
readings from Thorlabs' ASL5040-UV as OpticStudio wrote it (XDAT 1 = 0, k = -0.68): read as Qbfs with
this φ, every zone from 0.5 to 22.86 mm focuses within 0.5 µm of the file's image plane at its 405 nm
and the EFL is 40.000 mm, the catalogue's; read with the sphere's φ the rays beyond r = 17.4 mm find
no surface, with the conic's own 1/sqrt(1 - (1+k) c² r²) the zones spread over 0.6 mm, and read as
Qcon the paraxial focus is 3 mm short.

The sums are evaluated as Forbes prescribes for production ("Robust, efficient computational methods for
axially symmetric optical aspheres", Opt. Express 18, 19700 (2010)): Qbfs's coefficients are
changed once to the basis P_m (P_0 = 2, P_1 = 6 - 8x, P_(m+1) = (2 - 4x) P_m - P_(m-1)) and the sum
and its x-derivative come from one Clenshaw recurrence; Qcon's from the Clenshaw recurrence of the
Jacobi three-term relation. Both stay accurate to rounding for any number of terms, and are
polynomials in x: finite for any r (beyond r_n the surface is the polynomials' extrapolation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np

FORMS = ("qbfs", "qcon")


@dataclass(frozen=True)
class QType:
    """A Q-type departure: `form` qbfs or qcon, normalisation radius r_n (mm), coefficients a_0, a_1, ... (mm)."""

    form: Literal["qbfs", "qcon"]
    norm_radius: float
    coefficients: tuple[float, ...]

    @property
    def vertex_curvature(self) -> float:
        """What the departure adds to the vertex curvature (1/mm): Qbfs's u² (1 - u²) factor starts at
        r² / r_n², so z ≈ (c + 2 S(0) / r_n²) r² / 2 near the axis; Qcon's u⁴ adds none."""
        if self.form == "qcon":
            return 0.0
        return 2.0 * float(_clenshaw_bfs(self.coefficients, np.zeros(1))[0][0]) / self.norm_radius**2

    def departure(self, r2: np.ndarray, curvature: float, conic: float) -> tuple[np.ndarray, np.ndarray]:
        """(Δz, (dΔz/dr) / r) at squared radius r2 (n,): the Q-type part of the sag, and of its slope
        divided by r (finite at r = 0). Qbfs's φ is inf beyond the base conic's reach (where the
        base sag is inf too); never NaN."""
        r2 = np.asarray(r2, dtype=np.float64)
        rn2 = self.norm_radius * self.norm_radius
        x = r2 / rn2
        with np.errstate(invalid="ignore", over="ignore"):
            dz, g = self._departure(x, r2, rn2, curvature, conic)
        # Far outside any lens (x ~ 1e300) the polynomials overflow: inf, as beyond a conic's reach.
        return np.where(np.isnan(dz), np.inf, dz), np.where(np.isnan(g), np.inf, g)

    def _departure(self, x, r2, rn2, curvature, conic):
        if self.form == "qcon":
            s, ds = _clenshaw_con(self.coefficients, x)
            # z = x² S(x): dz/dx = 2x S + x² S', dx/dr = 2r / r_n²
            return x * x * s, 2.0 * x * (2.0 * s + x * ds) / rn2
        s, ds = _clenshaw_bfs(self.coefficients, x)
        c2 = curvature * curvature
        base = 1.0 - (1.0 + conic) * c2 * r2  # > 0 inside the base conic's reach
        ok = base > 0.0
        base = np.where(ok, base, 1.0)
        phi = np.sqrt((1.0 - conic * c2 * r2) / base)
        poly = x * (1.0 - x) * s
        dpoly = (1.0 - 2.0 * x) * s + x * (1.0 - x) * ds
        # d/dr [poly(x) φ] / r = (2 / r_n²) poly'(x) φ + poly φ' / r, with φ' / r = c² / (φ base²)
        # (d φ² / dr = 2 c² r / base²). Beyond the reach both are inf wholesale.
        dz = np.where(ok, poly * phi, np.inf)
        g = np.where(ok, 2.0 * dpoly * phi / rn2 + poly * c2 / (phi * base * base), np.inf)
        return dz, g


@lru_cache(maxsize=64)
def _bfs_to_p_basis(a: tuple[float, ...]) -> tuple[float, ...]:
    """Coefficients b_m with Σ a_m Q^bfs_m = Σ b_m P_m (Forbes 2010, eqs. A.14-A.16 and 3.5):
    P_m = f_m Q_m + g_(m-1) Q_(m-1) + h_(m-2) Q_(m-2), so a_m = f_m b_m + g_m b_(m+1) + h_m b_(m+2),
    solved from the top down."""
    n = len(a)
    f, g, h = np.zeros(n + 2), np.zeros(n + 2), np.zeros(n + 2)
    f[0], g[0], f[1] = 2.0, -0.5, math.sqrt(19.0) / 2.0
    for m in range(2, n + 2):
        h[m - 2] = -m * (m - 1) / (2.0 * f[m - 2])
        g[m - 1] = -(1.0 + g[m - 2] * h[m - 2]) / f[m - 1]
        f[m] = math.sqrt(m * (m + 1) + 3.0 - g[m - 1] ** 2 - h[m - 2] ** 2)
    b = [0.0] * (n + 2)
    for m in range(n - 1, -1, -1):
        b[m] = (a[m] - g[m] * b[m + 1] - h[m] * b[m + 2]) / f[m]
    return tuple(b[:n])


def _clenshaw_bfs(a: tuple[float, ...], x: np.ndarray):
    """Σ a_m Q^bfs_m(x) and its x-derivative: Clenshaw on P_(m+1) = (2 - 4x) P_m - P_(m-1); with
    P_1 - (2 - 4x) P_0 = 2 the sum is 2 (α_0 + α_1)."""
    b = _bfs_to_p_basis(tuple(float(v) for v in a))
    two_minus = 2.0 - 4.0 * x
    al1 = al2 = np.zeros_like(x)  # α_(m+1), α_(m+2)
    d1 = d2 = np.zeros_like(x)
    for bm in reversed(b):
        al0 = bm + two_minus * al1 - al2
        d0 = two_minus * d1 - d2 - 4.0 * al1
        al2, al1, d2, d1 = al1, al0, d1, d0
    return 2.0 * (al1 + al2), 2.0 * (d1 + d2)


@lru_cache(maxsize=64)
def _jacobi04_recurrence(n: int) -> tuple[tuple[float, float, float], ...]:
    """(A_m, B_m, C_m), m = 0..n: P_m = (A_m + B_m x) P_(m-1) - C_m P_(m-2) for P_m^(0,4)(2x - 1)
    (the three-term relation of Jacobi polynomials, α = 0, β = 4, with t = 2x - 1)."""
    out = [(0.0, 0.0, 0.0)]
    for m in range(1, n + 1):
        s = 2 * m + 4  # 2m + α + β
        den = 2.0 * m * (m + 4) * (s - 2)
        lin = (s - 1) * s * (s - 2)  # multiplies t
        const = (s - 1) * (0 - 16)  # (2m+α+β-1)(α² - β²)
        # t = 2x - 1: lin t + const = (const - lin) + 2 lin x
        out.append(((const - lin) / den, 2.0 * lin / den, 2.0 * (m - 1) * (m + 3) * s / den))
    return tuple(out)


def _clenshaw_con(a: tuple[float, ...], x: np.ndarray):
    """Σ a_m Q^con_m(x) and its x-derivative by Clenshaw on the Jacobi recurrence (P_0 = 1, P_-1 = 0)."""
    n = len(a)
    rec = _jacobi04_recurrence(n + 1)
    al1 = al2 = np.zeros_like(x)
    d1 = d2 = np.zeros_like(x)
    for m in range(n - 1, -1, -1):
        a_next, b_next, _ = rec[m + 1]
        c_next2 = rec[m + 2][2] if m + 2 <= n + 1 else 0.0
        al0 = a[m] + (a_next + b_next * x) * al1 - c_next2 * al2
        d0 = b_next * al1 + (a_next + b_next * x) * d1 - c_next2 * d2
        al2, al1, d2, d1 = al1, al0, d1, d0
    return al1, d1


__all__ = ["QType", "FORMS"]
