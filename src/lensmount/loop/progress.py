"""How a run is doing after each pass: value ± error, error trend, ETA, cost of the next halving.

A Monte Carlo error falls as 1/√t, so time ∝ 1/error²: reaching a target error ε
from the current ε₀ after t seconds takes t·(ε₀/ε)² in total, and halving the
error once more takes 3·t more (4·t in all).
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.analysis.metrics import stray_fraction
from lensmount.loop.simulate import PassStatus


def time_to_error(elapsed_s: float, rel_error: float, target: float) -> float | None:
    """Seconds still needed to reach `target` at the 1/√t rate (0 when reached; None when unknown)."""
    if not (math.isfinite(rel_error) and elapsed_s > 0 and target > 0):
        return None
    return max(elapsed_s * ((rel_error / target) ** 2 - 1.0), 0.0)


def next_halving_s(elapsed_s: float) -> float:
    """Seconds more to halve the current error (time ∝ 1/error²: 4× the time in total)."""
    return 3.0 * max(elapsed_s, 0.0)


MIN_TREND_POINTS = 6  # fits of fewer (rel. error, time) points over the last half of a run are noise
MAX_TREND_ERROR = 0.25  # a slope known worse than ±0.25 cannot tell 1/√t (−0.5) from a stalled error (0)


def error_trend(history: list[tuple[float, float]]) -> tuple[float, float] | None:
    """(slope, its standard error) of log(rel error) against log(time), least squares over the last
    half of the run; None until it means something: at least MIN_TREND_POINTS points with a known
    error, and a slope known to ±MAX_TREND_ERROR (7–8 passes gave t^+2.08, all noise)."""
    pts = [(t, e) for t, e in history if t > 0 and 0 < e < math.inf]
    pts = pts[len(pts) // 2:]
    if len(pts) < MIN_TREND_POINTS:
        return None
    x = np.log([t for t, _ in pts])
    y = np.log([e for _, e in pts])
    if np.ptp(x) == 0:
        return None
    (slope, _), cov = np.polyfit(x, y, 1, cov="unscaled")
    residual = y - np.polyval([slope, _], x)
    se = float(math.sqrt(max(cov[0, 0], 0.0) * float(residual @ residual) / (len(x) - 2)))
    return (float(slope), se) if se <= MAX_TREND_ERROR else None


def error_slope(history: list[tuple[float, float]]) -> float | None:
    """The slope of `error_trend` (None while it means nothing)."""
    trend = error_trend(history)
    return None if trend is None else trend[0]


def status_of(acc, elapsed: float, aperture_flux_mm2: float, target: float | None, max_passes: int | None,
              history: list[tuple[float, float]]) -> PassStatus:
    """The PassStatus of an Accumulator; appends (elapsed, rel error) to `history`."""
    rel = acc.rel_error()
    history.append((elapsed, rel))
    trend = error_trend(history)
    se = acc.flux_std_error
    tail = acc.tail()
    return PassStatus(
        passes=acc.n, photons=acc.photons, elapsed_s=elapsed, value=stray_fraction(acc.flux, aperture_flux_mm2),
        std_error=stray_fraction(se, aperture_flux_mm2) if math.isfinite(se) else None, rel_error=rel,
        error_slope=trend and trend[0], error_slope_se=trend and trend[1], target_rel_error=target,
        eta_s=time_to_error(elapsed, rel, target) if target else None, max_passes=max_passes,
        largest_over_median=tail.over_median, heavy_tail=tail.heavy)


__all__ = ["status_of", "time_to_error", "next_halving_s", "error_slope", "error_trend"]
