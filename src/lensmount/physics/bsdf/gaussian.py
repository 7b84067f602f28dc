"""Gaussian lobe around the specular direction.

The seed paper's case 3: "5 % reflectance within a lobe of 5° half-width".

| parameter        | meaning                                                        | valid     |
|------------------|----------------------------------------------------------------|-----------|
| `reflectance`    | ρ = albedo at normal incidence (fraction of the flux reflected) | [0, 1]*   |
| `half_width_deg` | h = half width at half maximum of the lobe, degrees             | (0, 90]   |

Scene file: ``{ model = "gaussian", reflectance = 0.05, half_width_deg = 5.0 }``.
(*) ρ is also capped so that the albedo stays ≤ 1 at every incidence angle; the
cap only bites for wide lobes with ρ close to 1 (the error message gives it).

Definition. Let r = 2(n·wi)n − wi be the mirror direction of wi and θ the angle
between wo and r. The lobe is Gaussian in the chord |wo − r| = 2 sin(θ/2)
(≈ θ to 0.1 % for θ < 5°):

    p(wo) = κ exp(−κ (1 − cosθ)) / (2π (1 − e^{−2κ}))         [1/sr, a density on the sphere]
    f(wi, wo) = ρ N p(wo) / c̄,   c̄ = (cosθi + cosθo) / 2

p is the von Mises–Fisher density; κ is set so that p falls to half its peak at
θ = h: κ = ln 2 / (2 sin²(h/2)). Dividing by the mean cosine c̄ makes the lobe
carry (close to) the fraction ρ of the incident flux at any incidence angle,
instead of the fraction ρ cosθi a plain constant lobe would give; N (≈ 1 for
narrow lobes) makes the albedo exactly ρ at normal incidence.

Reciprocity holds exactly: the angle between wo and mirror(wi) equals the angle
between wi and mirror(wo) (mirroring is an orthogonal involution), and c̄ is
symmetric. The horizon clips the lobe near grazing incidence, so there
albedo(wi) < ρ — `albedo` reports it (a one-dimensional quadrature, the φ
integral being done in closed form).

Sampling is exact for the lobe shape: 1 − cosθ from the inverse CDF of p (an
exponential law), φ uniform, in the frame of r; the pdf is p itself, finite and
accurate down to 0.01° half-widths (κ ≈ 5·10⁷). The weight f·cosθo/pdf =
ρN·2cosθo/(cosθi + cosθo) is bounded by 2ρN.
"""

from __future__ import annotations

import math

import numpy as np

from pydantic import Field

from lensmount.errors import InputError
from lensmount.physics.bsdf.base import (
    BSDF, BSDFS, COS_EPS, BSDFParams, TabulatedAlbedo, as_rows, dot, mirror, normalize, tangent_frame)

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(128)
_S = 0.5 * (_NODES + 1.0)  # Gauss–Legendre on [0, 1], then t = (1 − cos πs)/2 to cluster at both ends
_T = 0.5 * (1.0 - np.cos(math.pi * _S))
_TW = 0.5 * _WEIGHTS * 0.5 * math.pi * np.sin(math.pi * _S)
_CHUNK = 4096


class GaussianParams(BSDFParams):
    reflectance: float = Field(ge=0.0, le=1.0)
    half_width_deg: float = Field(gt=0.0, le=90.0)


@BSDFS.register("gaussian", GaussianParams)
class Gaussian(TabulatedAlbedo, BSDF):
    """Reciprocal Gaussian (von Mises–Fisher) lobe around the mirror direction; see the module docstring."""

    name = "gaussian"

    def __init__(self, params: GaussianParams):
        self.reflectance, self.half_width_deg = params.reflectance, params.half_width_deg
        self.lobe_half_width_deg = self.half_width_deg
        half = math.radians(self.half_width_deg)
        self.kappa = math.log(2.0) / (2.0 * math.sin(0.5 * half) ** 2)
        # Density p = self._peak · exp(−κ x), x = 1 − cosθ ∈ [0, 2].
        self._mass = -math.expm1(-2.0 * self.kappa)  # 1 − e^{−2κ}, the (x ≤ 2) normalisation
        self._peak = self.kappa / (2.0 * math.pi * self._mass)
        self._scale = 1.0 / float(self._lobe_fraction(np.ones(1))[0])  # N
        self.tis = self.reflectance
        self.weight_bound = 2.0 * self.reflectance * self._scale  # `sample`'s 2 cosθo / (cosθi + cosθo) < 2
        worst = self._worst_albedo_factor()
        if self.reflectance * worst > 1.0 + 1e-12:
            raise InputError(
                f"Gaussian lobe of half-width {self.half_width_deg:g}° with reflectance {self.reflectance:g} "
                f"would reflect {self.reflectance * worst:.4f} > 1 of the incident flux at some incidence angle",
                field="reflectance", valid=f"[0, {1.0 / worst:.4f}] for this half-width")

    @property
    def params(self):
        return {"reflectance": self.reflectance, "half_width_deg": self.half_width_deg}

    # -- geometry of the lobe -------------------------------------------------------------
    def _chord_x(self, wi, wo, n):
        """x = 1 − cos(angle(wo, mirror(wi))) = |wo − r|²/2: accurate for tiny angles (no 1 − cos cancellation)."""
        d = wo - mirror(wi, n)
        return np.minimum(0.5 * dot(d, d), 2.0)

    def eval(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        ci, co = dot(wi, n), dot(wo, n)
        live = (ci > COS_EPS) & (co > COS_EPS)
        p = self._peak * np.exp(-self.kappa * self._chord_x(wi, wo, n))
        mean_cos = np.where(live, 0.5 * (ci + co), 1.0)
        return np.where(live, self.reflectance * self._scale * p / mean_cos, 0.0)

    def pdf(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        live = (dot(wi, n) > COS_EPS) & (dot(wo, n) > COS_EPS)
        return np.where(live, self._peak * np.exp(-self.kappa * self._chord_x(wi, wo, n)), 0.0)

    def sample(self, wi, n, u):
        wi, n, u = as_rows(wi, "wi"), as_rows(n, "n"), np.asarray(u, dtype=np.float64)
        u = np.clip(u, 0.0, np.nextafter(1.0, 0.0))
        x = self._x_of_u(u[:, 0])
        cos_t = 1.0 - x
        sin_t = np.sqrt(np.maximum(x * (2.0 - x), 0.0))
        phi = 2.0 * math.pi * u[:, 1]
        r = normalize(mirror(wi, n))
        t1, t2 = tangent_frame(r)
        wo = normalize(cos_t[:, None] * r + (sin_t * np.cos(phi))[:, None] * t1
                       + (sin_t * np.sin(phi))[:, None] * t2)
        ci, co = dot(wi, n), dot(wo, n)
        live = (ci > COS_EPS) & (co > COS_EPS)
        pdf = np.where(live, self._peak * np.exp(-self.kappa * x), 0.0)
        denom = np.where(live, ci + co, 1.0)
        weight = np.where(live & (pdf > 0.0), self.reflectance * self._scale * 2.0 * co / denom, 0.0)
        return wo, weight, pdf

    def _x_of_u(self, u):
        """Inverse CDF of x = 1 − cosθ under p: x = −ln(1 − u(1 − e^{−2κ}))/κ ∈ [0, 2)."""
        with np.errstate(divide="ignore"):  # u·(1 − e^{−2κ}) = 1 only when e^{−2κ} underflows: x = 2 then
            return np.minimum(-np.log1p(-u * self._mass) / self.kappa, 2.0)

    # -- albedo ---------------------------------------------------------------------------
    def _albedo_exact(self, ci):
        """albedo at cosθi = ci (M,) by quadrature; `albedo` interpolates a table of it (TabulatedAlbedo)."""
        return self.reflectance * self._scale * self._lobe_fraction(np.clip(ci, 0.0, 1.0))

    def _lobe_fraction(self, ci: np.ndarray) -> np.ndarray:
        """E_p[2cosθo/(cosθi + cosθo); cosθo > 0] for cosθi = ci (M,) — the albedo over ρN.

        The expectation over p is a sum over the lobe's own quantile u (so narrow and wide
        lobes are resolved alike), split where the circle at angle θ from r starts to cross
        the horizon (θ = 90° − θi) and where it has sunk below it (θ = 90° + θi); on each
        panel, Gauss–Legendre after t = (1 − cos πs)/2 (clustering at the panel's square-root
        ends). For each θ the integral over φ is closed-form (`_phi_integral`).
        """
        theta_i = np.arccos(np.clip(ci, 0.0, 1.0))
        bounds = [np.zeros_like(ci), self._u_of_theta(0.5 * math.pi - theta_i),
                  self._u_of_theta(0.5 * math.pi + theta_i)]
        out = np.zeros(len(ci))
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            for start in range(0, len(ci), _CHUNK):
                a, b = lo[start:start + _CHUNK, None], hi[start:start + _CHUNK, None]
                u = a + (b - a) * _T[None, :]
                values = _phi_integral(ci[start:start + _CHUNK, None], self._x_of_u(u))
                out[start:start + _CHUNK] += (values * (b - a)) @ _TW / (2.0 * math.pi)
        return out

    def _u_of_theta(self, theta):
        """CDF of p at angle θ from r: (1 − e^{−κ(1 − cosθ)})/(1 − e^{−2κ})."""
        x = 2.0 * np.sin(0.5 * np.clip(theta, 0.0, math.pi)) ** 2
        return np.clip(-np.expm1(-self.kappa * x) / self._mass, 0.0, 1.0)

    def _worst_albedo_factor(self) -> float:
        """max over incidence of albedo/ρ (slightly above 1 for wide lobes at oblique incidence)."""
        elevation = np.concatenate([np.linspace(0.0, 90.0, 181)[1:],
                                    self.half_width_deg * np.geomspace(1e-3, 10.0, 60)])
        ci = np.sin(np.radians(elevation[elevation <= 90.0]))
        return float(np.max(self._scale * self._lobe_fraction(ci)))


def _phi_integral(ci: np.ndarray, x: np.ndarray) -> np.ndarray:
    """∫ 2cosθo/(cosθi + cosθo) dφ over the φ where cosθo > 0, at angle θ (x = 1 − cosθ) from r.

    With e ⊥ r in the plane of incidence, n = cosθi r + sinθi e, so cosθo = a + b cosφ with
    a = cosθ cosθi, b = sinθ sinθi. The integrand is 2 − 2ci/(ci + a + b cosφ); over
    |φ| < φm (cos φm = −a/b) that is 4φm − 4ci·I, I = ∫_0^φm dφ/(c + b cosφ), c = ci + a,
    done with t = tan(φ/2): I = 2T/(c + b)·F(z), z = (c − b)/(c + b)·T², F(z) = arctan(√z)/√z
    (z > 0) or artanh(√−z)/√−z (z < 0). Shapes broadcast (ci (M,1), x (1,K)) -> (M,K).
    """
    cos_t = 1.0 - x
    sin_t = np.sqrt(np.maximum(x * (2.0 - x), 0.0))
    si = np.sqrt(np.maximum(1.0 - ci * ci, 0.0))
    a = cos_t * ci
    b = sin_t * si
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(b > 1e-300, -a / np.maximum(b, 1e-300), np.where(a > 0.0, -2.0, 2.0))
    phim = np.arccos(np.clip(ratio, -1.0, 1.0))
    full = ratio <= -1.0  # the whole circle of directions at this θ is above the horizon
    c = ci + a
    # Whole circle: I = π/√(c² − b²) (c − b = ci + min cosθo ≥ ci > 0 there).
    i_full = math.pi / np.sqrt(np.maximum((c - b) * (c + b), 1e-300))
    half = np.minimum(phim, math.pi * (1.0 - 1e-12)) * 0.5
    tt = np.tan(half)
    cpb = np.maximum(c + b, 1e-300)
    z = (c - b) / cpb * tt * tt
    s = np.sqrt(np.abs(z))
    with np.errstate(divide="ignore", invalid="ignore"):
        f_pos = np.arctan(s) / np.maximum(s, 1e-300)
        f_neg = np.arctanh(np.minimum(s, 1.0 - 1e-16)) / np.maximum(s, 1e-300)
    series = 1.0 - z / 3.0 + z * z / 5.0
    fz = np.where(np.abs(z) < 1e-6, series, np.where(z > 0.0, f_pos, f_neg))
    i_part = 2.0 * tt / cpb * fz
    integral = np.where(full, i_full, i_part)
    result = 4.0 * np.where(full, math.pi, phim) - 4.0 * ci * integral
    return np.maximum(result, 0.0)
