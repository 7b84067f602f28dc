"""`compare`: two runs (result folders, or design folders simulated as needed) → verdict, difference image.

Runs are found in the results store by input hash, so a design state that was
simulated before is not simulated again (any seed: equal hashes differ only by noise).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from lensmount.analysis.compare import Measurement, Verdict, judge
from lensmount.errors import InputError
from lensmount.loop.simulate import Observer, SimulateOptions, planned_input_hash, simulate
from lensmount.store import RunRecord, Store, default_path

METRICS = {  # metric -> (value key, std error key, bias bound key) in summary.json
    "stray_fraction": ("stray_fraction", "stray_fraction_std_error", "stray_fraction_bias_bound"),
    "stray_flux_mm2": ("stray_flux_mm2", "stray_flux_std_error_mm2", None),
}
AGAINST = ("last", "best")


@dataclass(frozen=True)
class Run:
    """A finished run: its folder and summary.json."""

    folder: Path
    summary: dict

    @classmethod
    def load(cls, folder: str | Path, field: str) -> "Run":
        folder = Path(folder)
        path = folder / "summary.json"
        if not path.is_file():
            raise InputError("not a results folder (no summary.json)", file=str(folder), field=field,
                             valid="a folder written by `lensmount simulate`, or a design folder with --scene")
        try:
            return cls(folder, json.loads(path.read_text()))
        except ValueError as exc:
            raise InputError(f"summary.json is not valid JSON ({exc})", file=str(path), field=field) from None

    def measurement(self, metric: str) -> Measurement:
        value, error, bias = METRICS[metric]
        s = self.summary
        if s.get(value) is None:
            raise InputError(f"the run has no value of {metric}", file=str(self.folder / "summary.json"),
                             field="--metric", valid=", ".join(METRICS))
        return Measurement(float(s[value]), s.get(error), float(s.get(bias) or 0.0) if bias else 0.0,
                           int(s.get("passes", 2)), int(s.get("photons", 0)), float(s.get("time_s", 0.0)))

    def part(self, name: str) -> Measurement:
        p = self.summary.get("per_part", {}).get(name, {"fraction": 0.0, "std_error": 0.0})
        return Measurement(float(p.get("fraction") or 0.0), p.get("std_error"), float(p.get("bias_bound") or 0.0),
                           int(self.summary.get("passes", 2)), int(self.summary.get("photons", 0)),
                           float(self.summary.get("time_s", 0.0)))


@dataclass(frozen=True)
class CompareOptions:
    """a, b : result folders, or design folders with `scene`; with `against` only `a` is given
    (a design folder) and the old run comes from the store: "last", "best" or a git revision.
    tolerance : relative to the old value; confidence : of the interval on the change.
    out : folder for difference.exr/png and compare.json (default NEW/compare).
    simulate : options template for runs that must be simulated (design, scene, out are filled in)."""

    a: Path
    b: Path | None = None
    scene: str | None = None
    against: str | None = None
    metric: str = "stray_fraction"
    tolerance: float = 0.05
    confidence: float = 0.99
    out: Path | None = None
    store: Path | None = None
    method: str = "bidirectional"
    workers: int = 0


@dataclass
class CompareResult:
    old: Run
    new: Run
    verdict: Verdict
    per_part: dict[str, Verdict]
    metric: str
    paths: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """0: no significant regression (also undecided); 1: regression beyond the tolerance."""
        return 1 if self.verdict.regression else 0

    def to_dict(self) -> dict:
        def clean(v: Verdict) -> dict:
            return {k: (x if not isinstance(x, float) or math.isfinite(x) else None) for k, x in asdict(v).items()}

        return {"metric": self.metric, "old_run": str(self.old.folder.resolve()), "new_run": str(self.new.folder.resolve()),
                **clean(self.verdict), "per_part": {k: clean(v) for k, v in self.per_part.items()},
                "notes": self.notes, "exit_code": self.exit_code}


def _scene_file(design: Path, scene: str) -> Path:
    p = Path(scene)
    if p.suffix == ".toml" and p.is_file():
        return p
    candidate = design / "scenes" / f"{p.stem}.toml"
    if candidate.is_file():
        return candidate
    names = sorted(q.stem for q in (design / "scenes").glob("*.toml")) if (design / "scenes").is_dir() else []
    raise InputError(f"scene {scene!r} not found", file=str(design), field="--scene",
                     valid="a scene file, or one of: " + (", ".join(names) or "(no scenes/ in the design)"))


def current_run(design: Path, scene: str, o: CompareOptions, observer: Observer | None = None) -> Run:
    """The design folder's current state on `scene`: a stored run with the same input hash, else a new run."""
    from lensmount.design.folder import load_design
    from lensmount.design.scene import load_scene

    scene_path = _scene_file(design, scene)
    sim = SimulateOptions(design, scene_path, method=o.method, workers=o.workers, store=o.store)
    d = load_design(design)
    digest = planned_input_hash(sim, d, load_scene(scene_path))
    with Store(default_path(design, o.store)) as store:
        stored = [r for r in store.runs(input_hash=digest) if Path(r.summary_path).is_file()]
    if stored:
        return Run.load(Path(stored[-1].summary_path).parent, "DESIGN")
    out = Path(design).resolve() / ".lensmount" / "runs" / f"{scene_path.stem}-{digest[:12]}"
    result = simulate(replace(sim, out=out), observer)
    return Run(result.out, result.summary)


def stored_run(design: Path, scene: str, against: str, exclude_hash: str | None, o: CompareOptions) -> Run:
    """The old run of `design` on `scene` from the store: last (other inputs), best, or a git revision."""
    scene_name = Path(scene).stem
    with Store(default_path(design, o.store)) as store:
        runs = [r for r in store.runs(design_path=design, scene_name=scene_name) if Path(r.summary_path).is_file()]
    if not runs:
        raise InputError(f"no stored run of scene {scene_name!r} for this design", file=str(design),
                         field="--against", valid="simulate a revision first, or compare two result folders")
    pick: RunRecord | None
    if against == "last":
        others = [r for r in runs if r.input_hash != exclude_hash]
        pick = (others or runs)[-1]
    elif against == "best":
        pick = min((r for r in runs if r.stray_fraction is not None), key=lambda r: r.stray_fraction, default=None)
    else:
        matches = [r for r in runs if r.git_commit and r.git_commit.startswith(against.lower())]
        pick = matches[-1] if matches else None
    if pick is None:
        commits = sorted({r.git_commit[:10] for r in runs if r.git_commit})
        raise InputError(f"no stored run matches {against!r}", file=str(design), field="--against",
                         valid="last, best, or a stored git revision: " + (", ".join(commits) or "(none stored)"))
    return Run.load(Path(pick.summary_path).parent, "--against")


def check_comparable(old: Run, new: Run, metric: str) -> list[str]:
    """InputError when the two runs do not measure the same thing; notes for harmless differences."""
    if metric not in METRICS:
        raise InputError(f"unknown metric {metric!r}", field="--metric", valid=", ".join(METRICS))
    po, pn = old.summary.get("provenance", {}), new.summary.get("provenance", {})
    if po.get("scene_sha256") and pn.get("scene_sha256") and po["scene_sha256"] != pn["scene_sha256"]:
        raise InputError(f"the runs simulate different scenes ({po.get('scene_path')} vs {pn.get('scene_path')}; "
                         "the scene files differ)", file=str(new.folder), field="scene",
                         valid="two runs of the same scene file (source, detector, finishes, effects)")
    notes = []
    if old.summary.get("method") != new.summary.get("method"):
        notes.append(f"methods differ: {old.summary.get('method')} (old) vs {new.summary.get('method')} (new)")
    if sorted(old.summary.get("effects", [])) != sorted(new.summary.get("effects", [])):
        raise InputError("the runs simulate different effects", file=str(new.folder), field="effects",
                         valid=f"the same effects as the old run: {', '.join(old.summary.get('effects', []))}")
    return notes


def compare(options: CompareOptions, observer: Observer | None = None) -> CompareResult:
    """Compare two runs (see CompareOptions); writes difference.exr, difference.png, compare.json."""
    o = options
    if not 0 < o.confidence < 1:
        raise InputError(f"confidence {o.confidence:g} is out of range", field="--confidence",
                         valid="a fraction in (0, 1), e.g. 0.99 or 99%")
    if not o.tolerance >= 0:
        raise InputError(f"tolerance {o.tolerance:g} is negative", field="--tolerance", valid="≥ 0, e.g. 5%")
    a = Path(o.a)
    if o.against is not None:
        if o.b is not None or o.scene is None:
            raise InputError("--against takes one design folder and --scene", field="--against",
                             valid="lensmount compare DESIGN --scene S --against last|best|REV")
        new = current_run(a, o.scene, o, observer)
        old = stored_run(a, o.scene, o.against, new.summary.get("input_hash"), o)
    else:
        if o.b is None:
            raise InputError("compare needs two runs", field="B",
                             valid="two result folders, two design folders with --scene, or one design with --against")
        b = Path(o.b)
        if (a / "summary.json").is_file() or (b / "summary.json").is_file():
            old, new = Run.load(a, "A"), Run.load(b, "B")
        else:
            if o.scene is None:
                raise InputError("design folders need --scene", field="--scene", valid="a scene name or file")
            old, new = current_run(a, o.scene, o, observer), current_run(b, o.scene, o, observer)
    notes = check_comparable(old, new, o.metric)
    verdict = judge(old.measurement(o.metric), new.measurement(o.metric), o.tolerance, o.confidence)
    per_part = {}
    if o.metric == "stray_fraction":
        names = list(dict.fromkeys([*old.summary.get("per_part", {}), *new.summary.get("per_part", {})]))
        for name in names:
            per_part[name] = judge(old.part(name), new.part(name), o.tolerance, o.confidence)
    result = CompareResult(old, new, verdict, per_part, o.metric, notes=notes)
    out = Path(o.out) if o.out is not None else new.folder / "compare"
    result.paths = write_comparison(out, old, new, result)
    return result


def write_comparison(out: Path, old: Run, new: Run, result: CompareResult) -> dict[str, Path]:
    """difference.exr (Y = new − old, channels old and new), difference.png, compare.json."""
    from lensmount.results import read_exr, write_exr, write_summary

    a = read_exr(old.folder / "irradiance.exr")["Y"].astype(np.float64)
    b = read_exr(new.folder / "irradiance.exr")["Y"].astype(np.float64)
    if a.shape != b.shape:
        raise InputError(f"the detectors differ: {a.shape[1]}×{a.shape[0]} vs {b.shape[1]}×{b.shape[0]} pixels",
                         file=str(new.folder), field="detector", valid="two runs with the same detector")
    paths = {"exr": out / "difference.exr", "png": out / "difference.png", "json": out / "compare.json"}
    write_exr(paths["exr"], b - a, np.stack([a, b]), ["old", "new"], only_contributing=False)
    write_difference_preview(paths["png"], a, b, f"{result.metric}: {result.verdict.verdict}")
    write_summary(paths["json"], result.to_dict())
    return paths


def write_difference_preview(path: Path, old: np.ndarray, new: np.ndarray, title: str) -> None:
    """Old and new on one log colour scale, and new − old on a signed scale symmetric about 0."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm, SymLogNorm

    from lensmount.atomic import atomic_path

    positive = np.concatenate([old[old > 0], new[new > 0]])
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), dpi=90)
    if positive.size:
        hi = float(positive.max())
        norm = LogNorm(vmin=max(float(np.percentile(positive, 1)), hi * 1e-6), vmax=hi)
    else:
        norm = None
    for ax, img, name in ((axes[0], old, "old"), (axes[1], new, "new")):
        shown = np.where(img > 0, img, np.nan) if norm is not None else img
        im = ax.imshow(shown, origin="lower", cmap="inferno", norm=norm, interpolation="nearest")
        ax.set_title(f"{name} (E/E_sun, shared scale)", fontsize=9)
        fig.colorbar(im, ax=ax, fraction=0.046)
    diff = new - old
    span = float(np.abs(diff).max()) or 1.0
    linthresh = max(span * 1e-3, float(np.percentile(np.abs(diff[diff != 0]), 10)) if np.any(diff) else span)
    im = axes[2].imshow(diff, origin="lower", cmap="RdBu_r", interpolation="nearest",
                        norm=SymLogNorm(linthresh=linthresh, vmin=-span, vmax=span))
    axes[2].set_title("new − old (red: more stray light)", fontsize=9)
    fig.colorbar(im, ax=axes[2], fraction=0.046)
    for ax in axes:
        ax.set_xlabel("pixel x")
        ax.set_ylabel("pixel y")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    try:
        with atomic_path(path) as tmp:
            fig.savefig(str(tmp), format="png")
    finally:
        plt.close(fig)


__all__ = ["CompareOptions", "CompareResult", "Run", "compare", "current_run", "stored_run", "check_comparable",
           "METRICS"]
