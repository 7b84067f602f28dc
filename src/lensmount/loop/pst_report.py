"""What a PST sweep delivers: the curve judged against the scene's requirement, pst.csv, pst.png and report.html.

The verdict per angle (`judge`): the requirement's limit there (`RequirementSpec.limit`, log-linear between its
angles) against the point's interval at 99 % one-sided confidence, PST ± (Z99 standard errors + bias bound):

- `exceeds` when even its lower end is above the limit (what makes `lensmount pst` exit 1);
- `inside` when its upper end is at or below it (a zero reading: its upper bound, raised from 95 % to 99 %);
- `undecided` when the limit lies inside the interval, or the point has no error bar to judge with (none, or one
  pass dominating its spread): more passes, or a sampling that reaches the heavy paths, decide it;
- `not judged` outside the requirement's angles.

Angles are judged one by one; 99 % each, not jointly over the curve.

Two curves (two pst.csv: a mount revision's against the last) are compared angle by angle with the verdict of
`analysis.compare.judge` (the change's interval at the confidence asked, against the tolerance; a zero reading
as [0, its bound]): `compare_curves`, what `lensmount compare OLD NEW` does when both are PST folders.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lensmount.analysis.compare import Measurement, Verdict as ChangeVerdict, judge as judge_change
from lensmount.atomic import write_text
from lensmount.errors import InputError
from lensmount.loop.pst import PstPoint, PstResult
from lensmount.run.report import image_block, page, provenance_rows, section, table_block, write_report
from lensmount.run.results import save_figure

Z99 = 2.3263478740408408  # one-sided 99 % quantile of the normal
# A zero reading's bound at 99 % instead of 95 %: ln(100) expected photons instead of ln(20) = 3 (rule of three)
ZERO_99_OVER_95 = math.log(100.0) / 3.0
EXCEEDS, INSIDE, UNDECIDED, NOT_JUDGED = "exceeds", "inside", "undecided", "not judged"
BARS = ("bars: 1σ = standard error of the passes (batch means, Student's t) + tail allowance + kernel bias bound; "
        "open: no error bar to trust (see pst.csv's reason); ▽: nothing reached the detector, 95 % upper bound")


@dataclass(frozen=True)
class Verdict:
    """One angle against the requirement: limit (None: not judged), state (module docstring), and in words."""

    angle_deg: float
    limit: float | None
    state: str
    text: str


def judge(result: PstResult) -> list[Verdict]:
    """Every point against `result.requirement` (all `not judged` without one)."""
    return [_verdict(p, result.requirement.limit(p.angle_deg) if result.requirement else None) for p in result.points]


def _verdict(p: PstPoint, limit: float | None) -> Verdict:
    if limit is None:
        return Verdict(p.angle_deg, None, NOT_JUDGED, "")
    if p.upper_bound is not None:
        high = p.upper_bound * ZERO_99_OVER_95
        state = INSIDE if high <= limit else UNDECIDED
        return Verdict(p.angle_deg, limit, state, f"0 (below {high:.3g} at 99 %) against {limit:.3g}")
    if p.error is None or p.heavy:
        return Verdict(p.angle_deg, limit, UNDECIDED,
                       f"{p.pst:.3g} against {limit:.3g}, no error bar to judge with ({p.reason})")
    low, high = p.pst - Z99 * p.std_error - p.bias_bound, p.pst + Z99 * p.std_error + p.bias_bound
    state = EXCEEDS if low > limit else INSIDE if high <= limit else UNDECIDED
    return Verdict(p.angle_deg, limit, state, f"{p.pst:.3g} (99 %: {max(low, 0):.3g} to {high:.3g}) against {limit:.3g}")


def write_pst(out: Path, result: PstResult) -> dict[str, Path]:
    """pst.csv, pst.png (log scale, error bars, field edge, requirement) and report.html, atomically."""
    out = Path(out)
    paths = {"csv": out / "pst.csv", "png": out / "pst.png", "html": out / "report.html"}
    verdicts = judge(result)
    buffer = io.StringIO()
    table = csv.writer(buffer, lineterminator="\n")
    table.writerow(["angle_deg", "pst", "std_error", "upper_bound_95", "bias_bound", "in_field", "passes", "photons",
                    "time_s", "requirement", "verdict", "reason"])
    for p, v in zip(result.points, verdicts):
        table.writerow([f"{p.angle_deg:g}", f"{p.pst:.6g}", _num(p.std_error), _num(p.upper_bound), _num(p.bias_bound),
                        int(p.in_field), p.passes, p.photons, f"{p.time_s:.3f}", _num(v.limit),
                        "" if v.state == NOT_JUDGED else v.state, p.reason])
    write_text(paths["csv"], buffer.getvalue())
    plot_pst(paths["png"], result, verdicts)
    rows = [[f"{p.angle_deg:g}", f"{p.pst:.4g}" if p.upper_bound is None else f"0 (< {p.upper_bound:.2g})",
             "—" if p.std_error is None else f"{p.std_error:.2g}", "in field" if p.in_field else "outside", p.passes,
             f"{p.photons:,}", f"{p.time_s:.1f}", v.state if v.limit is not None else "", p.reason]
            for p, v in zip(result.points, verdicts)]
    blocks = [section("Point source transmittance", image_block("PST against off-axis angle", paths["png"])),
              section("Values", table_block(["angle (°)", "PST", "std. error", "", "passes", "photons", "time (s)",
                                             "requirement", "why no error bar"], rows)),
              section("Inputs and provenance", table_block(["field", "value"], provenance_rows(
                  {"method": result.method, "effects": result.effects, "azimuth_deg": result.azimuth_deg,
                   "field_edge_deg": result.field_edge_deg, "provenance": result.provenance})))]
    name = result.provenance.get("design_name", "")
    write_report(paths["html"], page(f"lensmount PST · {name}", blocks))
    return paths


def compare_curves(old: Path, new: Path, tolerance: float = 0.05, confidence: float = 0.99
                   ) -> tuple[list[tuple[float, ChangeVerdict]], list[str]]:
    """The angles both folders' pst.csv hold, each with the verdict on new − old (`analysis.compare.judge`), in the
    new curve's order; and a note per angle only one of them holds."""
    a, b = read_curve(old), read_curve(new)
    notes = [f"{angle:g}° only in the {name} curve" for name, mine, other in (("old", a, b), ("new", b, a))
             for angle in mine if angle not in other]
    return [(angle, judge_change(a[angle], m, tolerance, confidence)) for angle, m in b.items() if angle in a], notes


def read_curve(folder: Path) -> dict[float, Measurement]:
    """A pst.csv (of `write_pst`) as {angle: Measurement}: a zero reading with its upper bound as no signal, a
    blank std_error as unknown (inf: the run gave no error bar), a blank bias bound as not bounded."""
    path = Path(folder) / "pst.csv"
    if not path.is_file():
        raise InputError(f"no pst.csv in {folder}", file=str(path), valid="a folder `lensmount pst` wrote")
    curve = {}
    try:
        for row in csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"))):
            upper, se, bias = (row.get(k) or "" for k in ("upper_bound_95", "std_error", "bias_bound"))
            curve[float(row["angle_deg"])] = Measurement(
                float(row["pst"]), 0.0 if upper else float(se) if se else math.inf, float(bias) if bias else 0.0,
                passes=int(row["passes"]), photons=int(row["photons"]), time_s=float(row["time_s"]),
                no_signal_bound=float(upper) if upper else None,
                bias_unbounded=row.get("reason") or "not bounded" if "bias_bound" in row and not bias and not upper
                else None)
    except (KeyError, ValueError) as e:
        raise InputError(f"pst.csv cannot be read ({type(e).__name__}: {e})", file=str(path),
                         valid="a pst.csv as `lensmount pst` writes it") from None
    return curve


def _num(value: float | None) -> str:
    return "" if value is None else f"{value:.6g}"


def plot_pst(path: Path, result: PstResult, verdicts: list[Verdict] | None = None) -> None:
    """Log-scale PST: filled points with their 1σ bars (`BARS`), open points without a bar to trust, ▽ at the upper
    bound of a zero reading, the requirement (dashed) and the angles exceeding it (red rings)."""
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    verdicts = verdicts if verdicts is not None else judge(result)
    pts = result.points
    a = np.array([p.angle_deg for p in pts])
    v = np.array([p.pst for p in pts])
    e = np.array([p.error or 0.0 for p in pts])
    zero = np.array([p.upper_bound is not None for p in pts])
    upper = np.array([p.upper_bound or 0.0 for p in pts])
    barred = np.array([p.error is not None and not p.heavy for p in pts]) & ~zero & (v > 0)
    bare = ~barred & ~zero & (v > 0)
    shown = np.r_[v[v > 0], upper[zero & (upper > 0)]]
    floor = 0.3 * float(shown.min()) if len(shown) else 1e-12
    fig, ax = plt.subplots(figsize=(7.0, 4.6), dpi=100)
    ax.plot(a[v > 0], v[v > 0], "-", color="tab:blue", lw=1, alpha=0.6)
    lower = np.clip(np.minimum(e, v - 0.5 * floor), 0, None)  # keep the lower bar above zero on a log axis
    ax.errorbar(a[barred], v[barred], yerr=[lower[barred], e[barred]], fmt="o", ms=3.5, capsize=2, color="tab:blue",
                label=f"PST ({result.method}; {', '.join(result.effects) or 'no effects'})")
    if bare.any():
        ax.plot(a[bare], v[bare], "o", ms=5, mfc="white", color="tab:blue", label="no error bar to trust")
    if zero.any():
        ax.plot(a[zero], np.where(upper[zero] > 0, upper[zero], floor), "v", ms=6, mfc="white", color="0.3",
                label="0: 95 % upper bound")
    if result.requirement is not None:
        req = result.requirement
        ax.plot(req.angles_deg, req.pst_max, "--", color="k", lw=1.2, label="requirement")
        over = np.array([x.state == "exceeds" for x in verdicts])
        if over.any():
            ax.plot(a[over], v[over], "o", ms=10, mfc="none", mec="tab:red", mew=1.5,
                    label="exceeds it (99 %)")
    ax.axvline(result.field_edge_deg, color="tab:red", ls=":", lw=1, label=f"field edge {result.field_edge_deg:g}°")
    ax.set_yscale("log")
    ax.set_xlim(left=min(0.0, float(a.min()) if len(a) else 0.0))
    ax.set_xlabel("off-axis angle (°)")
    ax.set_ylabel("PST = E_detector / E_entrance")
    ax.set_title(f"point source transmittance · azimuth {result.azimuth_deg:g}°", fontsize=9)
    fig.text(0.01, 0.01, BARS, fontsize=6, color="0.3", wrap=True)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    save_figure(fig, path)


__all__ = ["Verdict", "judge", "compare_curves", "read_curve", "write_pst", "plot_pst", "Z99", "EXCEEDS", "INSIDE",
           "UNDECIDED", "NOT_JUDGED", "BARS"]
