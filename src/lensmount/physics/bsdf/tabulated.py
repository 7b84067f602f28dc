"""Tabulated scatter: a measured BRDF as a lobe in direction-cosine space, and the ABg fit to it.

| parameter | meaning                                                              | valid                      |
|-----------|----------------------------------------------------------------------|----------------------------|
| `rho`     | nodes of |β − β0| (direction cosines), increasing                     | ≥ 2 values in (0, 2]       |
| `brdf`    | f at the nodes, 1/sr                                                 | ≥ 0, non-increasing        |

    f(wi, wo) = interpolation of `brdf` at ρ = |β − β0|, linear in log f vs log ρ;
                f(ρ < rho[0]) = brdf[0]; beyond rho[-1] the last segment's log-log slope continues.

This is the Harvey–Shack reduction stray-light engineers apply to measured data: the
lobe depends on the incidence only through the shift of the specular direction β0, so
measurements at several incidences fold into one table (`measured_profile`). Scene
files give the measurement instead (`{ model = "tabulated", file = "paint.bsdf" }`, a
Zemax tabular BSDF or a CSV of incidence, scatter angle and BRDF; `design.brdf_data`
reads it). Like ABg and Harvey, the table is rejected when TIS > 1, and sampling, pdf
and albedo come from `radial.py`, so the same chi-square tests apply.

`fit_abg(rho, f)` fits A/(B + ρ^g) to measured points by least squares in log f, the
usual way of turning a measurement into the industry's three numbers.
"""

from __future__ import annotations

import math

import numpy as np

from pydantic import field_validator

from lensmount.errors import InputError
from lensmount.physics.bsdf.base import BSDFS, BSDFParams
from lensmount.physics.bsdf.radial import DirectionCosineLobe

_FLOOR = 1e-30  # log of a zero BRDF value


class TabulatedParams(BSDFParams):
    """A measured table (rho, brdf); a scene's [finishes] may give the measurement's `file` instead."""

    rho: list[float]
    brdf: list[float]

    @field_validator("rho", "brdf", mode="before")
    @classmethod
    def _listed(cls, value):
        """A table made in Python (`measured_profile`) comes as arrays."""
        return value.tolist() if isinstance(value, np.ndarray) else value


@BSDFS.register("tabulated", TabulatedParams)
class Tabulated(DirectionCosineLobe):
    """f(|β − β0|) from a table; reciprocal; TIS ≤ 1 enforced."""

    name = "tabulated"

    def __init__(self, params: TabulatedParams):
        rho = np.asarray(params.rho, np.float64).ravel()
        f = np.asarray(params.brdf, np.float64).ravel()
        if len(rho) < 2 or len(rho) != len(f) or not (np.all(np.isfinite(rho)) and np.all(np.isfinite(f))):
            raise InputError("a tabulated BSDF needs at least two finite (rho, brdf) pairs of equal length",
                             field="rho", valid="rho and brdf arrays of the same length ≥ 2")
        if rho[0] <= 0.0 or np.any(np.diff(rho) <= 0.0) or rho[-1] > 2.0:
            raise InputError("tabulated BSDF nodes must increase within (0, 2]", field="rho",
                             valid="increasing |β − β0| values in (0, 2]")
        if np.any(f < 0.0) or np.any(np.diff(f) > 0.0):
            raise InputError("tabulated BSDF values must be ≥ 0 and not increase away from the specular "
                             "direction", field="brdf", valid="non-increasing values ≥ 0 (measured_profile "
                                                             "makes such a table from measurements)")
        self.rho, self.brdf = rho, f
        self._log_rho = np.log(rho)
        self._log_f = np.log(np.maximum(f, _FLOOR))
        tail = (self._log_f[-1] - self._log_f[-2]) / (self._log_rho[-1] - self._log_rho[-2])
        self._tail_slope = min(tail, 0.0)
        half = f[0] / 2.0
        below = np.flatnonzero(f <= half)
        shoulder = float(np.interp(math.log(half), self._log_f[::-1], self._log_rho[::-1])) if below.size else None
        width = math.exp(shoulder) if shoulder is not None else math.inf
        self.lobe_half_width_deg = math.degrees(math.asin(width)) if width < 1.0 else math.inf
        self._build(min(float(rho[0]) * 10.0, 1.0), field="brdf",
                    valid="a measured table whose TIS ∫_{|β|<1} f d²β is at most 1")

    @property
    def params(self):
        return {"nodes": float(len(self.rho))}

    def profile(self, rho):
        r = np.log(np.maximum(np.asarray(rho, np.float64), self.rho[0]))
        inside = np.interp(r, self._log_rho, self._log_f)
        beyond = self._log_f[-1] + self._tail_slope * (r - self._log_rho[-1])
        return np.exp(np.where(r > self._log_rho[-1], beyond, inside))


def measured_profile(rho: np.ndarray, f: np.ndarray, bins_per_decade: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Measured points (ρ, f) from any incidences → a table for `Tabulated`.

    Points are binned in log ρ (median per bin: robust to a speckled measurement), then
    made non-increasing from the specular direction outward (the running minimum), which
    removes noise that would otherwise make the lobe rise again.
    """
    rho, f = np.asarray(rho, np.float64).ravel(), np.asarray(f, np.float64).ravel()
    keep = np.isfinite(rho) & np.isfinite(f) & (rho > 0.0) & (rho <= 2.0) & (f >= 0.0)
    rho, f = rho[keep], f[keep]
    if len(rho) < 2:
        raise InputError("the measurement has fewer than two usable points", field="brdf",
                         valid="BRDF values ≥ 0 at scatter directions above the surface")
    lo, hi = math.log10(rho.min()), math.log10(rho.max())
    edges = np.linspace(lo, hi, max(2, int(math.ceil((hi - lo) * bins_per_decade)) + 1))
    which = np.clip(np.searchsorted(edges, np.log10(rho), side="right") - 1, 0, len(edges) - 2)
    nodes, values = [], []
    for k in np.unique(which):
        sel = which == k
        nodes.append(float(np.exp(np.mean(np.log(rho[sel])))))
        values.append(float(np.median(f[sel])))
    return np.asarray(nodes), np.minimum.accumulate(np.asarray(values))


def fit_abg(rho: np.ndarray, f: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares ABg fit in log f: returns (A, B, g, rms error of log10 f)."""
    from scipy.optimize import least_squares  # lazy: keeps lensmount --help from loading scipy.optimize

    rho, f = np.asarray(rho, np.float64), np.asarray(f, np.float64)
    keep = (rho > 0.0) & (f > 0.0) & np.isfinite(rho) & np.isfinite(f)
    rho, f = rho[keep], f[keep]
    if len(rho) < 3:
        raise InputError("an ABg fit needs at least three points with BRDF > 0", field="brdf",
                         valid="a measurement with ≥ 3 positive BRDF values")
    log_f = np.log(f)

    def residual(x):
        log_a, log_b, g = x
        return log_a - np.logaddexp(log_b, g * np.log(rho)) - log_f

    peak = float(f.max())
    # Start: the shoulder at the ρ where f falls to half its peak, the wing's log-log slope for g.
    g0 = float(np.clip(-np.polyfit(np.log(rho[rho > np.median(rho)]), log_f[rho > np.median(rho)], 1)[0]
                       if np.sum(rho > np.median(rho)) >= 2 else 2.0, 0.1, 9.0))
    b0 = max(float(np.interp(0.5 * peak, f[np.argsort(f)], rho[np.argsort(f)])) ** g0, 1e-12)
    x0 = np.array([math.log(peak * b0), math.log(b0), g0])
    fit = least_squares(residual, x0, bounds=([-80.0, -80.0, 0.0], [20.0, 20.0, 10.0]))
    log_a, log_b, g = fit.x
    rms = float(np.sqrt(np.mean(fit.fun ** 2)) / math.log(10.0))
    return math.exp(log_a), math.exp(log_b), float(g), rms


__all__ = ["Tabulated", "measured_profile", "fit_abg"]
