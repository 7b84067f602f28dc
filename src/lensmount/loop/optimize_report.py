"""A study's records (the candidates, the common-random-numbers effect, the result) and its report:
OUT/optimize.json (everything), OUT/history.csv (one row per candidate) and
OUT/history.png (the objective per candidate with ±2σ bars, the incumbent's line, infeasible ones marked)."""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from lensmount.analysis.compare import Verdict
from lensmount.atomic import atomic_path, write_text
from lensmount.loop.optimize_spec import OptimizeSpec


@dataclass
class Candidate:
    """One design revision the search evaluated. `values` by variable key; `runs` maps passes →
    (stray fraction, standard error) on the search's seed; infeasible candidates say why."""

    index: int  # -1: the start
    values: dict
    folder: Path
    feasible: bool = True
    why: str = ""
    length_mm: float | None = None
    outer_diameter_mm: float | None = None
    runs: dict[int, tuple[float, float]] = field(default_factory=dict)
    incumbent: bool = False

    @property
    def passes(self) -> int:
        return max(self.runs, default=0)

    @property
    def value(self) -> float | None:
        return self.runs[self.passes][0] if self.runs else None

    @property
    def std_error(self) -> float | None:
        return self.runs[self.passes][1] if self.runs else None

    def to_dict(self) -> dict:
        return {"index": self.index, "values": self.values, "folder": str(self.folder), "feasible": self.feasible,
                "why": self.why, "length_mm": self.length_mm, "outer_diameter_mm": self.outer_diameter_mm,
                "runs": {str(k): list(v) for k, v in self.runs.items()}, "incumbent": self.incumbent}

    @classmethod
    def from_dict(cls, d: dict) -> "Candidate":
        return cls(d["index"], d["values"], Path(d["folder"]), d["feasible"], d["why"], d["length_mm"],
                   d["outer_diameter_mm"], {int(k): tuple(v) for k, v in d["runs"].items()}, d["incumbent"])


@dataclass(frozen=True)
class CrnEffect:
    """The variance of a per-pass difference between two nearby designs, with shared and with independent seeds."""

    shared_variance: float
    independent_variance: float
    passes: int
    nearby: dict

    @property
    def ratio(self) -> float:
        return self.shared_variance / self.independent_variance if self.independent_variance > 0 else math.nan


@dataclass
class OptimizeResult:
    spec: OptimizeSpec
    start: Candidate
    best: Candidate
    candidates: list[Candidate]
    crn: CrnEffect
    search_seeds: tuple[int, ...]
    verdict_seed: int | None = None
    verdict: Verdict | None = None
    revision: Path | None = None
    run_id: int | None = None
    importances: dict[str, float] = field(default_factory=dict)
    paths: dict[str, Path] = field(default_factory=dict)
    finished: bool = False  # every trial evaluated (else the budget stopped it: run again to resume)




def write_report(result: OptimizeResult, out: Path) -> dict[str, Path]:
    out = Path(out)
    paths = {"json": out / "optimize.json", "csv": out / "history.csv", "png": out / "history.png"}
    write_text(paths["json"], json.dumps(to_dict(result), indent=2, allow_nan=False))
    write_text(paths["csv"], _csv(result))
    _plot(result, paths["png"])
    return paths


def _finite(x):
    return x if not isinstance(x, float) or math.isfinite(x) else None


def to_dict(r: OptimizeResult) -> dict:
    v = r.verdict
    return {
        "finished": r.finished,
        "search_seeds": list(r.search_seeds), "verdict_seed": r.verdict_seed,
        "crn": {"shared_variance": r.crn.shared_variance, "independent_variance": r.crn.independent_variance,
                "ratio": _finite(r.crn.ratio), "passes": r.crn.passes, "nearby": r.crn.nearby},
        "start": _row(r.start), "best": _row(r.best),
        "verdict": None if v is None else {k: _finite(getattr(v, k)) for k in (
            "verdict", "old", "new", "change", "relative_change", "low", "high", "confidence", "note")},
        "revision": None if r.revision is None else str(r.revision), "run_id": r.run_id,
        "importances": r.importances,
        "candidates": [_row(c) for c in r.candidates],
    }


def _row(c: Candidate) -> dict:
    d = c.to_dict()
    d["runs"] = {k: [_finite(x) for x in v] for k, v in d["runs"].items()}
    return {**d, "value": _finite(c.value), "std_error": _finite(c.std_error), "passes": c.passes}


def _csv(r: OptimizeResult) -> str:
    keys = list(r.spec.variables)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["candidate", *keys, "stray_fraction", "std_error", "passes", "feasible", "incumbent", "length_mm",
                "outer_diameter_mm", "why"])
    for c in [r.start, *r.candidates]:
        w.writerow(["start" if c.index < 0 else c.index, *(c.values[k] for k in keys),
                    "" if c.value is None else f"{c.value:.6g}",
                    "" if c.std_error is None or not math.isfinite(c.std_error) else f"{c.std_error:.3g}",
                    c.passes, c.feasible, c.incumbent, _num(c.length_mm), _num(c.outer_diameter_mm),
                    " ".join(c.why.split())])
    return buf.getvalue()


def _num(x) -> str:
    return "" if x is None else f"{x:.3f}"


def _plot(r: OptimizeResult, path: Path) -> None:
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    ok = [c for c in r.candidates if c.feasible and c.value is not None]
    top = max([c.value + 2 * _bar(c) for c in ok + [r.start]], default=1.0)
    ax.errorbar([c.index + 1 for c in ok], [c.value for c in ok], yerr=[2 * _bar(c) for c in ok], fmt="o",
                capsize=3, label="candidate (bars ±2σ; more passes: a contender)")
    ax.axhline(r.start.value, color="0.4", ls="--", label="start")
    ax.axhline(r.best.value, color="tab:green", ls=":", label="incumbent at the end (re-evaluated)")
    bad = [c.index + 1 for c in r.candidates if not c.feasible]
    if bad:
        ax.plot(bad, [0.0] * len(bad), "x", color="tab:red", label="infeasible (optimize.json says why)")
    ax.set_ylim(0, 1.1 * top)
    ax.set_xlabel("candidate")
    ax.set_ylabel("stray fraction (search seed)")
    ax.set_title("optimize: the objective per candidate, common random numbers")
    ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)


def _bar(c: Candidate) -> float:
    return c.std_error if c.std_error is not None and math.isfinite(c.std_error) else 0.0


__all__ = ["Candidate", "CrnEffect", "OptimizeResult", "to_dict", "write_report"]
