"""What accuracy costs in time: each method's error at doubling budgets.

One run per method (through `lensmount.loop.simulate`, so exactly what `simulate` does)
with a time budget; the run's state is read after every pass and kept at the first pass
past each level t_k = T / 2^(L-1-k), so the levels double in time. Per level: elapsed
time, passes, photons, the stray fraction, its relative standard error (batch means), and
the relative error against a reference when one is given (a long run's summary.json, or
an analytic value). The bias bound comes from the run's summary when the estimator gives
one; it is known at the last level only (the summary is written once per run).

A Monte Carlo error falls as t^-1/2; the fitted slope of log(error) against log(t) says
whether a method does (a bidirectional run whose radius bias still dominates falls slower).
The next halving of the error takes t·(2^(1/|slope|) − 1) more seconds at the fitted rate
(3·t at the ideal −½). Only levels with at least MIN_PASSES_FOR_SLOPE passes enter the
fit; the first levels need many short passes (a small --photons-per-pass) to count.

Levels are snapshots of one run each, so they are nested, not independent: the curve
shows one run's progress, as an engineer would watch it, at the cost of the largest level
only rather than the sum of all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from lensmount.atomic import write_text
from lensmount.errors import InputError
from lensmount.integrators.registry import INTEGRATORS
from lensmount.loop.simulate import Observer, SimulateOptions, simulate
from lensmount.run.results import read_summary, save_figure

MIN_PASSES_FOR_SLOPE = 4


@dataclass(frozen=True)
class ConvergeOptions:
    """budget_s : total seconds of tracing, shared equally by the methods; levels : doublings."""

    design: Path
    scene: Path
    out: Path
    methods: tuple[str, ...] = field(default_factory=INTEGRATORS.names)
    budget_s: float = 600.0
    levels: int = 5
    reference: float | None = None  # stray fraction to measure the error against
    photons_per_pass: int | None = None
    seed: int | None = None
    workers: int = 0


@dataclass(frozen=True)
class Level:
    method: str
    level: int
    time_s: float
    passes: int
    photons: int
    value: float
    std_error: float | None
    rel_std_error: float | None
    bias_bound: float | None = None
    rel_error_vs_reference: float | None = None
    rel_error: float | None = None  # (standard error + bias bound) / value: what --target-rel-error stops on


@dataclass
class MethodCurve:
    method: str
    levels: list[Level]
    slope: float | None  # fitted d log(rel std error) / d log(t)
    next_halving_s: float | None  # seconds more to halve the error (None: no error bar yet)
    summary: dict = field(default_factory=dict)
    halving_rate: str = "fitted"  # "fitted" slope, or "1/√t" when the fit is outside PLAUSIBLE_SLOPES


# A fitted slope outside this range comes from error bars on few passes, not from the method:
# the halving time is then given at the Monte Carlo rate 1/√t instead.
PLAUSIBLE_SLOPES = (-1.5, -0.25)


def read_reference(text: str | None) -> float | None:
    """A number, or the path of a summary.json whose stray_fraction is the reference."""
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        path = Path(text)
        if not path.is_file():
            raise InputError("reference not found", file=text, field="--reference",
                             valid="a stray fraction (e.g. 1.5e-6) or a long run's summary.json") from None
        try:
            value = read_summary(path, "--reference")["stray_fraction"]
        except (KeyError, TypeError):
            raise InputError("no stray_fraction in this file", file=text, field="--reference",
                             valid="a summary.json written by lensmount simulate") from None
    if value is None or not (math.isfinite(float(value)) and float(value) > 0):
        raise InputError(f"the reference must be a positive stray fraction, got {value}", field="--reference",
                         valid="a number > 0 or a summary.json with a positive stray_fraction")
    return float(value)


def level_times(budget_s: float, levels: int) -> list[float]:
    """t_k = budget / 2^(levels-1-k): doubling times ending at the budget."""
    return [budget_s / 2 ** (levels - 1 - k) for k in range(levels)]


def fit_slope(times: list[float], errors: list[float | None]) -> float | None:
    """Least-squares slope of log(error) on log(time) (None with fewer than 2 usable points)."""
    pts = [(t, e) for t, e in zip(times, errors) if t > 0 and e is not None and 0 < e < math.inf]
    if len(pts) < 2 or len({t for t, _ in pts}) < 2:
        return None
    x, y = np.log([t for t, _ in pts]), np.log([e for _, e in pts])
    return float(np.polyfit(x, y, 1)[0])


def halving_time(elapsed_s: float, slope: float | None) -> float | None:
    """Seconds more to halve the error at error ∝ t^slope (None when the error does not fall)."""
    if slope is None or not slope < -1e-3:
        return None
    return elapsed_s * (2.0 ** (1.0 / -slope) - 1.0)


def check(o: ConvergeOptions) -> None:
    bad = [m for m in o.methods if m not in INTEGRATORS]
    if bad or not o.methods:
        raise InputError(f"unknown method(s) {', '.join(bad) or '(none)'}", field="--methods",
                         valid="a comma-separated list of " + ", ".join(INTEGRATORS.names()))
    if not (o.budget_s > 0 and math.isfinite(o.budget_s)):
        raise InputError(f"--budget must be a positive number of seconds, got {o.budget_s:g}", field="--budget",
                         valid="seconds > 0, e.g. 600")
    if not 2 <= o.levels <= 12:
        raise InputError(f"--levels must be between 2 and 12, got {o.levels}", field="--levels",
                         valid="an integer 2…12 (each level doubles the time)")
    if o.photons_per_pass is not None and o.photons_per_pass < 1:
        raise InputError("--photons-per-pass must be at least 1", field="--photons-per-pass", valid="an integer ≥ 1")


def converge(o: ConvergeOptions, progress: Callable[[str], None] | None = None) -> list[MethodCurve]:
    """Run each method for budget/len(methods) seconds and read it at the doubling levels."""
    check(o)
    say = progress or (lambda text: None)
    per_method = o.budget_s / len(o.methods)
    times = level_times(per_method, o.levels)
    curves = []
    for method in o.methods:
        statuses = []

        class Watch(Observer):
            def stage(self, text: str) -> None:
                say(f"{method}: {text}")

            def pass_done(self, status) -> None:
                statuses.append(status)

        say(f"{method}: {per_method:.0f} s, levels at " + ", ".join(f"{t:.3g}" for t in times) + " s")
        run = simulate(SimulateOptions(o.design, o.scene, method=method, seed=o.seed, out=Path(o.out) / method,
                                       time_s=per_method, photons_per_pass=o.photons_per_pass, workers=o.workers,
                                       record=False), Watch())
        run.raise_if_stopped("the convergence study stopped: run it again")
        curves.append(_curve(method, statuses, times, run.summary, o.reference))
        last = curves[-1].levels[-1] if curves[-1].levels else None
        if last is not None:
            say(f"{method}: {last.passes} passes, stray fraction {last.value:.4g}, rel. std. error "
                f"{_pct(last.rel_std_error)}")
    return curves


def _curve(method, statuses, times, summary, reference) -> MethodCurve:
    levels, k = [], 0
    for s in statuses:
        last = s is statuses[-1]
        while k < len(times) and (s.elapsed_s >= times[k] or (last and k == len(times) - 1)):
            # All passes zero (nothing reached the detector yet) is no error bar of 0: unknown.
            # rel_std_error is the standard error alone (the 1/√t curve); (se + bias)/value is `rel_error`.
            signal = s.value != 0 and s.std_error is not None
            rel_se = s.std_error / abs(s.value) if signal else None
            rel = s.rel_error if signal and math.isfinite(s.rel_error) else None
            bias = summary.get("stray_fraction_bias_bound") if last else None
            vs_ref = abs(s.value - reference) / reference if reference else None
            levels.append(Level(method, k, s.elapsed_s, s.passes, s.photons, s.value, s.std_error, rel_se, bias, vs_ref,
                                rel))
            k += 1
    # Several levels can fall on one pass when passes are long: keep the distinct points.
    distinct = [lv for i, lv in enumerate(levels) if i == 0 or lv.passes != levels[i - 1].passes]
    # An error bar from n passes is itself uncertain by ~1/√(2(n−1)) (±71 % at n = 2): fit
    # the slope only where it means something.
    fitted = [lv for lv in distinct if lv.passes >= MIN_PASSES_FOR_SLOPE]
    slope = fit_slope([lv.time_s for lv in fitted], [lv.rel_std_error for lv in fitted])
    rate, halving = "fitted", None
    if distinct and distinct[-1].rel_std_error is not None:
        if slope is not None and PLAUSIBLE_SLOPES[0] <= slope <= PLAUSIBLE_SLOPES[1]:
            halving = halving_time(distinct[-1].time_s, slope)
        else:
            rate, halving = "1/√t", halving_time(distinct[-1].time_s, -0.5)
    return MethodCurve(method, distinct, slope, halving, summary, rate)


def _pct(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.2f} %"


def write_converge(out: Path, curves: list[MethodCurve], reference: float | None = None) -> dict[str, Path]:
    """converge.csv and converge.png (log-log error against time, 1/√t drawn) in out."""
    out = Path(out)
    paths = {"csv": out / "converge.csv", "png": out / "converge.png"}
    cols = ["method", "level", "time_s", "passes", "photons", "stray_fraction", "std_error", "rel_std_error",
            "bias_bound", "rel_error", "rel_error_vs_reference"]
    lines = [",".join(cols)]
    for c in curves:
        for lv in c.levels:
            vals = [lv.method, lv.level, f"{lv.time_s:.3f}", lv.passes, lv.photons, f"{lv.value:.6g}",
                    lv.std_error, lv.rel_std_error, lv.bias_bound, lv.rel_error, lv.rel_error_vs_reference]
            lines.append(",".join("" if v is None else (f"{v:.6g}" if isinstance(v, float) else str(v)) for v in vals))
    write_text(paths["csv"], "\n".join(lines) + "\n")
    plot_converge(paths["png"], curves, reference)
    return paths


def plot_converge(path: Path, curves: list[MethodCurve], reference: float | None) -> None:
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    fig, ax = plt.subplots(figsize=(6.4, 4.6), dpi=100)
    for c, color in zip(curves, ("tab:blue", "tab:orange", "tab:green")):
        pts = [(lv.time_s, lv.rel_std_error) for lv in c.levels if lv.rel_std_error]
        if not pts:
            if c.levels and c.levels[-1].value == 0:
                ax.plot([], [], " ", label=f"{c.method}: nothing reached the detector "
                                           f"({c.levels[-1].photons:,} photons, {c.levels[-1].time_s:.0f} s)")
            continue
        t, e = np.array(pts).T
        slope = f", slope {c.slope:+.2f}" if c.slope is not None else ""
        ax.loglog(t, e, "o-", color=color, label=f"{c.method}: rel. std. error{slope}")
        # The ideal 1/√t through the first point.
        guide = np.geomspace(t[0], t[-1] * 2, 20)
        ax.loglog(guide, e[0] * np.sqrt(t[0] / guide), ":", color=color, lw=1)
        vs = [(lv.time_s, lv.rel_error_vs_reference) for lv in c.levels if lv.rel_error_vs_reference]
        if vs:
            tv, ev = np.array(vs).T
            ax.loglog(tv, ev, "x", color=color, label=f"{c.method}: |error| vs reference")
        bias = [(lv.time_s, lv.bias_bound / lv.value) for lv in c.levels if lv.bias_bound and lv.value > 0]
        if bias:
            tb, eb = np.array(bias).T
            ax.loglog(tb, eb, "s", mfc="none", color=color, label=f"{c.method}: bias bound (relative)")
    ax.plot([], [], ":", color="0.3", label="1/√t")
    ax.xaxis.set_minor_formatter(NullFormatter())  # minor labels overlap on a log axis
    ax.set_xlabel("wall time (s; shared CPU, noisy)")
    ax.set_ylabel("relative error of the stray fraction")
    ax.set_title("error against time" + (f" · reference {reference:.4g}" if reference else ""), fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


__all__ = ["ConvergeOptions", "Level", "MethodCurve", "converge", "write_converge", "plot_converge",
           "read_reference", "level_times", "fit_slope", "halving_time"]
