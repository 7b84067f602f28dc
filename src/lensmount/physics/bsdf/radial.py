"""Lobes that depend only on |β − β0| in direction-cosine space (ABg, Harvey–Shack).

β is the projection of wo on the surface's tangent plane, β0 that of the mirror
direction of wi (so β0 = −wi's projection and β − β0 = wo_t + wi_t: the model is
reciprocal). Since cosθo dωo = d²β, the hemisphere is the unit disc |β| < 1 and

    albedo(wi) = ∫_{|β|<1} f(|β − β0|) d²β,     TIS = albedo at normal incidence (β0 = 0).

For f decreasing in |β − β0| the disc centred on β0 = 0 collects the most, so
albedo(wi) ≤ TIS at every incidence: checking TIS ≤ 1 at load time conserves
energy everywhere (the parameter ranges keep f non-increasing).

Sampling: ρ = |β − β0| from a tabulated radial law on a log grid of rings
(built once per parameter set) up to ρmax = 1 + |β0| (the farthest point of the
disc), φ uniform, β = β0 + ρ(cosφ, sinφ); a β outside the unit disc is a dead
lane. The sampling density q is f at the grid nodes, linear in ρ² between them
(so its CDF is quadratic in ρ² and inverts in closed form); `pdf` returns
exactly q/Z·cosθo, Z = ∫_{ρ<ρmax} q d²β, so sample and pdf agree to rounding,
and the weight f/q·Z stays within a fraction of a percent of Z.

`albedo` integrates ∫ f(ρ) Δφ(ρ) ρ dρ directly (Δφ: the arc of the circle of
radius ρ about β0 inside the unit disc): exact ring integrals up to 1 − |β0|,
then Gauss–Legendre on intervals graded geometrically toward both ends of the
band 1 − |β0| < ρ < 1 + |β0| (square-root ends of Δφ, and the lobe's peak when
β0 nears the rim at grazing incidence).
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.errors import InputError
from lensmount.physics.bsdf.base import BSDF, COS_EPS, TabulatedAlbedo, as_rows, dot, normalize, tangent_frame

_RINGS_PER_DECADE = 96
_CHUNK = 2048


class DirectionCosineLobe(TabulatedAlbedo, BSDF):
    """Base of ABg and Harvey. Subclasses define `profile(rho)` and call `_build(core_scale, field, valid)`."""

    def profile(self, rho: np.ndarray) -> np.ndarray:
        """f (1/sr) as a function of ρ = |β − β0| ≥ 0, (M,) -> (M,); finite and non-increasing."""
        raise NotImplementedError

    # -- tables ---------------------------------------------------------------------------
    def _build(self, core_scale: float, field: str, valid: str) -> None:
        """Ring grid, exact ring integrals (TIS, albedo), the sampling law's CDF; InputError if TIS > 1."""
        rho_lo = max(min(1e-3 * core_scale, 1e-4), 1e-14)
        decades = math.log10(1.0 / rho_lo)
        inner = np.geomspace(rho_lo, 1.0, int(math.ceil(decades * _RINGS_PER_DECADE)) + 1)
        outer = np.geomspace(1.0, 2.0, 49)[1:]
        self._edges = np.concatenate([[0.0], inner, outer])
        self._v = self._edges**2  # ρ² at the ring edges
        # Exact ∫_ring f d²β by Gauss–Legendre per ring (in ln ρ except the innermost disc).
        masses = _ring_integral(self.profile, self._edges[:-1], self._edges[1:])
        self._exact_cum = np.concatenate([[0.0], np.cumsum(masses)])
        self.tis = float(self._exact_cum[len(inner)])  # edges[len(inner)] == 1.0
        if self.tis > 1.0:
            raise InputError(
                f"BSDF '{self.name}' {self._param_text()} has total integrated scatter {self.tis:.4g} > 1 "
                f"(it would reflect more light than it receives)", field=field, valid=valid)
        # Sampling law: q = f at the nodes, linear in v = ρ²; ring mass π Δv (q_k + q_k+1)/2.
        self._q = self.profile(self._edges)
        self._dv = np.diff(self._v)
        self._slope = np.diff(self._q) / self._dv
        self._cum = np.concatenate([[0.0], np.cumsum(math.pi * self._dv * 0.5 * (self._q[:-1] + self._q[1:]))])

    def _param_text(self) -> str:
        return ", ".join(f"{k} = {v:g}" for k, v in self.params.items())

    def _ring_of(self, v):
        return np.clip(np.searchsorted(self._v, v, side="right") - 1, 0, len(self._dv) - 1)

    def _sampling_cdf(self, v):
        """∫_{ρ² < v} q d²β for v (M,) in [0, 4]."""
        k = self._ring_of(v)
        t = v - self._v[k]
        return self._cum[k] + math.pi * (self._q[k] * t + 0.5 * self._slope[k] * t * t)

    def _density(self, v):
        """q at ρ² = v (M,), the un-normalised sampling density in the β plane."""
        return np.interp(v, self._v, self._q)

    # -- geometry -------------------------------------------------------------------------
    @staticmethod
    def _tangential(w, n):
        return w - dot(w, n)[:, None] * n

    def eval(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        live = (dot(wi, n) > COS_EPS) & (dot(wo, n) > COS_EPS)
        d = self._tangential(wo, n) + self._tangential(wi, n)  # β − β0
        return np.where(live, self.profile(np.sqrt(dot(d, d))), 0.0)

    def pdf(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        co = dot(wo, n)
        wi_t = self._tangential(wi, n)
        d = self._tangential(wo, n) + wi_t
        b = np.sqrt(dot(wi_t, wi_t))
        z = self._sampling_cdf(np.minimum((1.0 + b) ** 2, 4.0))
        live = (dot(wi, n) > COS_EPS) & (co > COS_EPS) & (z > 0.0)
        return np.where(live, self._density(dot(d, d)) / np.where(live, z, 1.0) * co, 0.0)

    def sample(self, wi, n, u):
        wi, n, u = as_rows(wi, "wi"), as_rows(n, "n"), np.asarray(u, dtype=np.float64)
        u = np.clip(u, 0.0, np.nextafter(1.0, 0.0))
        t1, t2 = tangent_frame(n)
        beta0 = -np.stack([dot(wi, t1), dot(wi, t2)], axis=1)
        b = np.sqrt(np.sum(beta0 * beta0, axis=1))
        z = self._sampling_cdf(np.minimum((1.0 + b) ** 2, 4.0))
        # Invert the CDF: ring k, then the root t of π(q_k t + slope t²/2) = target − cum_k.
        target = u[:, 0] * z
        k = np.clip(np.searchsorted(self._cum, target, side="right") - 1, 0, len(self._dv) - 1)
        c = np.maximum(target - self._cum[k], 0.0) / math.pi
        qk, sk = self._q[k], self._slope[k]
        disc = np.sqrt(np.maximum(qk * qk + 2.0 * sk * c, 0.0))
        root = 2.0 * c / np.maximum(qk + disc, 1e-300)  # the stable form of (−q + √(q² + 2sc))/s
        v = self._v[k] + np.clip(root, 0.0, self._dv[k])
        rho = np.sqrt(v)
        phi = 2.0 * math.pi * u[:, 1]
        beta = beta0 + rho[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        co = np.sqrt(np.maximum(1.0 - np.sum(beta * beta, axis=1), 0.0))
        wo = normalize(beta[:, :1] * t1 + beta[:, 1:] * t2 + co[:, None] * n)
        q = self._density(v)
        live = (dot(wi, n) > COS_EPS) & (co > COS_EPS) & (z > 0.0) & (q > 0.0)
        pdf = np.where(live, q / np.where(live, z, 1.0) * co, 0.0)
        weight = np.where(live, self.profile(rho) * z / np.where(live, q, 1.0), 0.0)
        return wo, weight, pdf

    def _albedo_exact(self, ci):
        """∫_{|β|<1} f(|β−β0|) d²β at cosθi = ci (M,): full circles up to ρ = 1 − b, then the arcs Δφ(ρ)
        inside the disc. `albedo` interpolates a table of it (TabulatedAlbedo)."""
        b_all = np.sqrt(np.maximum(1.0 - np.clip(ci, 0.0, 1.0) ** 2, 0.0))
        out = np.zeros(len(ci))
        for start in range(0, len(ci), _CHUNK):
            b = b_all[start:start + _CHUNK]
            out[start:start + _CHUNK] = self._full_circles(1.0 - b) + self._arcs(b)
        return out

    def _full_circles(self, rho):
        """∫_{|β|<ρ} f d²β (exact ring sums plus the partial ring by Gauss–Legendre), rho (M,) in [0, 1]."""
        k = self._ring_of(rho * rho)
        lo = self._edges[k]
        return self._exact_cum[k] + _ring_integral(self.profile, lo, np.maximum(rho, lo), nodes=16)

    def _arcs(self, b):
        """∫_{1−b}^{1+b} f(ρ) Δφ(ρ) ρ dρ, with nodes graded toward both ends (b (M,))."""
        bb = b[:, None]
        total = np.zeros(len(b))
        for rho in (1.0 - bb + bb * _TAU[None, :], 1.0 + bb - bb * _TAU[None, :]):
            with np.errstate(divide="ignore", invalid="ignore"):
                c = (1.0 - bb * bb - rho * rho) / np.maximum(2.0 * rho * bb, 1e-300)
            arc = 2.0 * math.pi - 2.0 * np.arccos(np.clip(c, -1.0, 1.0))
            total += (self.profile(rho.ravel()).reshape(rho.shape) * arc * rho) @ _TAU_W * b
        return total


def _ring_integral(profile, lo, hi, nodes: int = 8):
    """∫_{lo<|β|<hi} f d²β = 2π ∫ f ρ dρ per ring, (M,): Gauss–Legendre in ln ρ (in ρ when lo = 0)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    t, w = 0.5 * (x + 1.0), 0.5 * w
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    use_log = lo > 0.0
    log_lo = np.log(np.where(use_log, lo, 1.0))
    log_hi = np.log(np.where(use_log, np.maximum(hi, lo), 1.0))
    rho_log = np.exp(log_lo[:, None] + (log_hi - log_lo)[:, None] * t[None, :])
    rho_lin = lo[:, None] + (hi - lo)[:, None] * t[None, :]
    rho = np.where(use_log[:, None], rho_log, rho_lin)
    # weight for ∫ g ρ dρ: in ln ρ it is Δlnρ·w·ρ², linearly Δρ·w·ρ
    weight = np.where(use_log[:, None], (log_hi - log_lo)[:, None] * w * rho**2, (hi - lo)[:, None] * w * rho)
    f = profile(rho.ravel()).reshape(rho.shape)
    return 2.0 * math.pi * np.sum(weight * f, axis=1)


def _graded_nodes(decades: int = 14, per_decade: int = 3, order: int = 8):
    """Gauss–Legendre nodes and weights on [0, 1], on intervals graded geometrically toward 0."""
    edges = np.concatenate([[0.0], np.geomspace(10.0**-decades, 1.0, decades * per_decade + 1)])
    x, w = np.polynomial.legendre.leggauss(order)
    lo, hi = edges[:-1, None], edges[1:, None]
    return (lo + (hi - lo) * 0.5 * (x + 1.0)).ravel(), ((hi - lo) * 0.5 * w).ravel()


_TAU, _TAU_W = _graded_nodes()
