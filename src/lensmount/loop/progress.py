"""How a run is doing after each pass: value ± error, error trend, ETA, cost of the next halving.

A Monte Carlo error falls as 1/√t, so time ∝ 1/error²: reaching a target error ε
from the current ε₀ after t seconds takes t·(ε₀/ε)² in total, and halving the
error once more takes 3·t more (4·t in all).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.analysis.error_bar import MIN_PASSES
from lensmount.analysis.metrics import stray_fraction
from lensmount.run.runner import Stopping


@dataclass(frozen=True)
class PassStatus:
    """The run after a merged pass, as an engineer watches it.

    value, std_error : stray fraction and its standard error (None before 2 passes)
    rel_error : relative error of the total (inf when unknown)
    error_slope : d log(rel error) / d log(time) over the last half of the run (≈ −0.5 when it converges
        as 1/√t); None until enough passes make it more than noise (loop.progress.error_trend)
    error_slope_se : its standard error
    eta_s : seconds to the target relative error at the rate so far (None without a target, or while the
        relative error is unknown past the first passes: no signal yet, an unbounded bias)
    largest_over_median : the largest pass / the median pass (None before any pass or with a median of 0)
    heavy_tail : one pass dominates the others (`Accumulator.tail`): the error is not the spread's, and
        the target is not met however small the relative error reads
    """

    passes: int
    photons: int
    elapsed_s: float
    value: float
    std_error: float | None
    rel_error: float
    error_slope: float | None
    target_rel_error: float | None
    eta_s: float | None
    max_passes: int | None
    largest_over_median: float | None = None
    heavy_tail: bool = False
    error_slope_se: float | None = None
    rel_error_unknown: str = ""  # why rel_error is not known ("" when it is): few passes, no signal, the bias


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


def expected_s(rule: Stopping, photons_per_pass: int, stored: list, done_passes: int = 0):
    """(seconds, passes, the stored run it goes by) that `rule` will take, or None without a stored run
    with an error to go by (`stored`: RunRecords of the same scene, newest last; see
    simulate.stored_like): the newest one's error at the 1/√photons rate, its seconds per pass scaled
    to this run's photons per pass; within the minimum and maximum passes and the time cap."""
    usable = [r for r in stored if r.passes and r.photons and r.time_s > 0 and r.stray_fraction
              and r.stray_fraction_std_error is not None]
    if not usable:
        return None
    r = usable[-1]
    # a pass's cost grows slower than its photons (the view map's share is fixed): √ is the rough middle
    per_pass_s = r.time_s / r.passes * (photons_per_pass / (r.photons / r.passes)) ** 0.5
    passes = rule.max_passes
    if rule.target_rel_error is not None:
        rel = (r.stray_fraction_std_error + (r.stray_fraction_bias_bound or 0.0)) / r.stray_fraction
        needed = math.ceil(r.photons * (rel / rule.target_rel_error) ** 2 / photons_per_pass)
        passes = min(max(needed, rule.min_passes), rule.max_passes)
    seconds = max(passes - done_passes, 0) * per_pass_s
    return min(seconds, rule.time_s) if rule.time_s is not None else seconds, passes, r


def forecast(rule: Stopping, photons_per_pass: int, stored: list, done_passes: int = 0) -> str:
    """What `simulate` says before it starts: about how long its stopping rule will take (`expected_s`);
    without a stored run to go by, that the first passes will tell (the progress line does)."""
    cap = f"; stops at {rule.time_s:.0f} s of tracing at the latest" if rule.time_s is not None else ""
    goal = f"{100 * rule.target_rel_error:g} %" if rule.target_rel_error is not None else f"{rule.max_passes} passes"
    expected = expected_s(rule, photons_per_pass, stored, done_passes)
    if expected is None:
        return f"estimate: {goal}{cap}; no stored run of this scene with an error bar to go by, the first " \
               "passes will tell"
    seconds, passes, r = expected
    rel = ((r.stray_fraction_std_error + (r.stray_fraction_bias_bound or 0.0)) / r.stray_fraction)
    basis = f"from stored run {r.id}: {r.passes} passes × {r.photons // r.passes:,} photons, {100 * rel:.1f} % " \
            f"in {r.time_s:.0f} s"
    left = max(passes - done_passes, 0)  # a resumed run: what is left, not the whole run
    count = f"{left} more passes ({passes} in all, {done_passes} done)" if done_passes else f"{passes} passes"
    if rule.time_s is not None and seconds >= rule.time_s:
        return f"estimate: {goal} would take about {count}, more than the time cap: it stops at " \
               f"{rule.time_s:.0f} s first ({basis})"
    if rule.target_rel_error is None:  # the goal is the passes: say them once
        return f"estimate: {count} in about {seconds:.0f} s{cap} ({basis})"
    return f"estimate: {goal} in about {seconds:.0f} s{' more' if done_passes else ''}, {count}{cap} ({basis})"


def status_of(acc, elapsed: float, aperture_flux_mm2: float, target: float | None, max_passes: int | None,
              history: list[tuple[float, float]], min_passes: int = Stopping.min_passes) -> PassStatus:
    """The PassStatus of an Accumulator; appends (elapsed, rel error) to `history`. Before the error
    is known (fewer than 3 passes) the ETA is the minimum passes' at the speed so far: the least it takes."""
    rel = acc.rel_error()
    least = max(min_passes - acc.n, 0) * elapsed / max(acc.n, 1)
    unknown = "" if math.isfinite(rel) else (
        f"fewer than {MIN_PASSES} passes" if acc.n < MIN_PASSES else "no signal yet" if acc.flux == 0
        else "the kernel bias is not bounded yet")
    # before the error bar exists the least time is the minimum passes'; once the passes say nothing of
    # the error (no signal, an unbounded bias), no time to the target can be told
    eta = time_to_error(elapsed, rel, target) if target else None
    eta = max(eta, least) if eta is not None else least if target and acc.n < MIN_PASSES else None
    history.append((elapsed, rel))
    trend = error_trend(history)
    se = acc.flux_std_error
    tail = acc.tail()
    return PassStatus(
        passes=acc.n, photons=acc.photons, elapsed_s=elapsed, value=stray_fraction(acc.flux, aperture_flux_mm2),
        std_error=stray_fraction(se, aperture_flux_mm2) if math.isfinite(se) else None, rel_error=rel,
        error_slope=trend and trend[0], error_slope_se=trend and trend[1], target_rel_error=target,
        eta_s=eta, max_passes=max_passes, largest_over_median=tail.over_median, heavy_tail=tail.heavy,
        rel_error_unknown=unknown)


__all__ = ["PassStatus", "expected_s", "forecast", "status_of", "time_to_error", "next_halving_s", "error_slope", "error_trend"]
