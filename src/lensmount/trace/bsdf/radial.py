"""Lobes that depend only on |β − β0| in direction-cosine space (ABg, Harvey–Shack).

β is the projection of wo on the surface's tangent plane, β0 that of the mirror
direction of wi (so β0 = −wi's projection and β − β0 = wo_t + wi_t: the model is
reciprocal). Since cosθo dωo = d²β, the hemisphere is the unit disc |β| < 1 and

    albedo(wi) = ∫_{|β|<1} f(|β − β0|) d²β,     TIS = albedo at normal incidence (β0 = 0).

For f decreasing in |β − β0| the disc centred on β0 = 0 collects the most, so
albedo(wi) ≤ TIS at every incidence: checking TIS ≤ 1 at load time conserves
energy everywhere (the parameter ranges keep f non-increasing).

Sampling: ρ = |β − β0| from a tabulated radial CDF on a log grid of rings
(built once per parameter set) up to ρmax = 1 + |β0| (the farthest point of the
disc), φ uniform, β = β0 + ρ(cosφ, sinφ); a β outside the unit disc is a dead
lane. Within each ring the sampling density is uniform in area (the CDF is
linear in ρ²), and `pdf` returns exactly that piecewise-constant density times
cosθo, so sample and pdf agree to rounding; the weight f/pdf_β stays within a
few % of the ring's mean, and the estimator is unbiased whatever the grid.
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.errors import InputError
from lensmount.trace.bsdf.base import BSDF, COS_EPS, as_rows, dot, normalize, tangent_frame

_RINGS_PER_DECADE = 96
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_CHUNK = 2048


class DirectionCosineLobe(BSDF):
    """Base of ABg and Harvey. Subclasses define `profile(rho)` and call `_build(core_scale, field)`."""

    def profile(self, rho: np.ndarray) -> np.ndarray:
        """f (1/sr) as a function of ρ = |β − β0| ≥ 0, (M,) -> (M,); finite and non-increasing."""
        raise NotImplementedError

    # -- table ----------------------------------------------------------------------------
    def _build(self, core_scale: float, field: str, valid: str) -> None:
        """Ring grid, ring masses, cumulative CDF, albedo quadrature nodes, TIS; InputError if TIS > 1."""
        rho_lo = min(1e-3 * core_scale, 1e-4) if core_scale > 0 else 1e-4
        rho_lo = max(rho_lo, 1e-14)
        decades = math.log10(1.0 / rho_lo)
        inner = np.geomspace(rho_lo, 1.0, int(math.ceil(decades * _RINGS_PER_DECADE)) + 1)
        outer = np.geomspace(1.0, 2.0, 49)[1:]
        edges = np.concatenate([[0.0], inner, outer])
        self._edges2 = edges**2
        lo, hi = edges[:-1], edges[1:]
        # Quadrature nodes per ring for ∫ g(ρ) ρ dρ: in ln ρ (ρ² d ln ρ) except the innermost disc.
        t = 0.5 * (_GL_X + 1.0)
        w = 0.5 * _GL_W
        rho_q = np.empty((len(lo), len(t)))
        w_q = np.empty_like(rho_q)
        rho_q[0] = lo[0] + (hi[0] - lo[0]) * t
        w_q[0] = (hi[0] - lo[0]) * w * rho_q[0]
        log_lo, log_hi = np.log(lo[1:]), np.log(hi[1:])
        rho_q[1:] = np.exp(log_lo[:, None] + (log_hi - log_lo)[:, None] * t[None, :])
        w_q[1:] = (log_hi - log_lo)[:, None] * w[None, :] * rho_q[1:] ** 2
        f_q = self.profile(rho_q.ravel()).reshape(rho_q.shape)
        ring_mass = 2.0 * math.pi * np.sum(w_q * f_q, axis=1)  # ∫_ring f d²β
        self._cdf = np.concatenate([[0.0], np.cumsum(ring_mass)])
        area = math.pi * (self._edges2[1:] - self._edges2[:-1])
        self._ring_density = ring_mass / area  # mean f over each ring = sampling density × Z
        self._rho_q, self._wf_q = rho_q.ravel(), (w_q * f_q).ravel()
        self.tis = float(self._cdf[len(inner)])  # edges[len(inner)] == 1.0
        if self.tis > 1.0:
            raise InputError(
                f"BSDF '{self.name}' {self._param_text()} has total integrated scatter {self.tis:.4g} > 1 "
                f"(it would reflect more light than it receives)", field=field, valid=valid)

    def _param_text(self) -> str:
        return ", ".join(f"{k} = {v:g}" for k, v in self.params.items())

    def _cdf_at(self, rho2: np.ndarray) -> np.ndarray:
        """Tabulated ∫_{|β−β0|<ρ} f d²β, linear in ρ² within each ring (the sampled law exactly)."""
        return np.interp(rho2, self._edges2, self._cdf)

    def _density_at(self, rho2: np.ndarray) -> np.ndarray:
        """Piecewise-constant (per ring) density × Z at ρ² (M,)."""
        k = np.clip(np.searchsorted(self._edges2, rho2, side="right") - 1, 0, len(self._ring_density) - 1)
        return self._ring_density[k]

    # -- geometry -------------------------------------------------------------------------
    @staticmethod
    def _tangential(w, n):
        return w - dot(w, n)[:, None] * n

    def eval(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        live = (dot(wi, n) > COS_EPS) & (dot(wo, n) > COS_EPS)
        d = self._tangential(wo, n) + self._tangential(wi, n)  # β − β0
        rho = np.sqrt(dot(d, d))
        return np.where(live, self.profile(rho), 0.0)

    def pdf(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        co = dot(wo, n)
        live = (dot(wi, n) > COS_EPS) & (co > COS_EPS)
        d = self._tangential(wo, n) + self._tangential(wi, n)
        b = np.sqrt(np.maximum(dot(self._tangential(wi, n), self._tangential(wi, n)), 0.0))
        z = self._cdf_at(np.minimum((1.0 + b) ** 2, 4.0))
        live &= z > 0.0
        pdf_beta = self._density_at(dot(d, d)) / np.where(live, z, 1.0)
        return np.where(live, pdf_beta * co, 0.0)

    def sample(self, wi, n, u):
        wi, n, u = as_rows(wi, "wi"), as_rows(n, "n"), np.asarray(u, dtype=np.float64)
        u = np.clip(u, 0.0, np.nextafter(1.0, 0.0))
        t1, t2 = tangent_frame(n)
        beta0 = -np.stack([dot(wi, t1), dot(wi, t2)], axis=1)
        b = np.sqrt(np.sum(beta0 * beta0, axis=1))
        z = self._cdf_at(np.minimum((1.0 + b) ** 2, 4.0))
        target = u[:, 0] * z
        k = np.clip(np.searchsorted(self._cdf, target, side="right") - 1, 0, len(self._ring_density) - 1)
        mass = self._cdf[k + 1] - self._cdf[k]
        frac = np.clip((target - self._cdf[k]) / np.where(mass > 0.0, mass, 1.0), 0.0, 1.0)
        rho2 = self._edges2[k] + frac * (self._edges2[k + 1] - self._edges2[k])
        rho = np.sqrt(rho2)
        phi = 2.0 * math.pi * u[:, 1]
        beta = beta0 + rho[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        beta2 = np.sum(beta * beta, axis=1)
        co = np.sqrt(np.maximum(1.0 - beta2, 0.0))
        wo = normalize(beta[:, :1] * t1 + beta[:, 1:] * t2 + co[:, None] * n)
        live = (dot(wi, n) > COS_EPS) & (co > COS_EPS) & (z > 0.0) & (mass > 0.0)
        density = self._ring_density[k]
        pdf = np.where(live, density / np.where(live, z, 1.0) * co, 0.0)
        weight = np.where(live, self.profile(rho) * z / np.where(live, density, 1.0), 0.0)
        return wo, weight, pdf

    def albedo(self, wi, n):
        """∫_{|β|<1} f(|β−β0|) d²β = ∫ f(ρ) Δφ(ρ) ρ dρ, Δφ the arc of the circle |β−β0| = ρ inside the disc."""
        wi, n = as_rows(wi, "wi"), as_rows(n, "n")
        ci = dot(wi, n)
        b_all = np.sqrt(np.maximum(1.0 - np.minimum(ci, 1.0) ** 2, 0.0))
        out = np.zeros(len(ci))
        rho = self._rho_q[None, :]
        for start in range(0, len(ci), _CHUNK):
            b = b_all[start:start + _CHUNK, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                c = np.where(b > 0.0, (1.0 - b * b - rho * rho) / np.maximum(2.0 * rho * b, 1e-300),
                             np.where(rho < 1.0, 2.0, -2.0))
            arc = 2.0 * math.pi - 2.0 * np.arccos(np.clip(c, -1.0, 1.0))
            out[start:start + _CHUNK] = arc @ self._wf_q
        return np.where(ci > COS_EPS, out, 0.0)
