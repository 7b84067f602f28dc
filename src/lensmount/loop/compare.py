"""`compare`: two runs (result folders, or design folders simulated as needed) → verdict, difference image.

Runs are found in the results store by input hash, so a design state that was
simulated before is not simulated again (any seed: equal hashes differ only by noise).
"""

from __future__ import annotations

import json
import math
import zipfile
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from lensmount.analysis.compare import Measurement, Verdict, judge
from lensmount.errors import InputError
from lensmount.loop.simulate import Observer, SimulateOptions, planned_input_hash, simulate
from lensmount.run.results import read_summary
from lensmount.run.store import RunRecord, Store, default_path

METRICS = {  # metric -> (value key, std error key, bias bound key) in summary.json
    "stray_fraction": ("stray_fraction", "stray_fraction_std_error", "stray_fraction_bias_bound"),
    "stray_flux_mm2": ("stray_flux_mm2", "stray_flux_std_error_mm2", "stray_flux_bias_bound_mm2"),
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
        return cls(folder, read_summary(path, field))

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
    method, workers, passes, photons_per_pass, time_s : for runs that must be simulated (unset: the
        scene's [run] table); a stored run is reused when its input hash matches."""

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
    passes: int | None = None
    photons_per_pass: int | None = None
    time_s: float | None = None


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
    from lensmount.loop.prepare import read_inputs

    scene_path = _scene_file(design, scene)
    sim = SimulateOptions(design, scene_path, method=o.method, workers=o.workers, store=o.store, passes=o.passes,
                          photons_per_pass=o.photons_per_pass, time_s=o.time_s)
    digest = planned_input_hash(sim, *read_inputs(design, scene_path))
    with Store(default_path(design, o.store)) as store:
        stored = [r for r in store.runs(input_hash=digest) if Path(r.summary_path).is_file()]
    if stored:
        return Run.load(Path(stored[-1].summary_path).parent, "DESIGN")
    out = Path(design).resolve() / ".lensmount" / "runs" / f"{scene_path.stem}-{digest[:12]}"
    result = simulate(replace(sim, out=out), observer)
    result.raise_if_stopped("no comparison made: run the same compare again")
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
    else:  # a revision: git's name for it (HEAD~1, a tag) or a prefix of a stored commit id
        from lensmount.loop.provenance import resolve_revision

        commit = resolve_revision(design, against) or against.lower()
        matches = [r for r in runs if r.git_commit and r.git_commit.startswith(commit)]
        pick = max(matches, key=lambda r: (not r.git_dirty, r.id)) if matches else None  # clean runs first
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
    if old.folder.resolve() == new.folder.resolve():
        notes.append("old and new are the same stored run: the store holds no run of other inputs to compare with")
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


def _std_error_image(run: Run, shape) -> np.ndarray:
    """Per-pixel standard error from the run's checkpoint (the pass sums), zeros when it has none
    (or one this version cannot read): it only sets the preview's pixel binning."""
    from lensmount.analysis.passes import Accumulator
    from lensmount.loop.simulate import CHECKPOINT

    path = run.folder / CHECKPOINT
    if path.is_file():
        try:
            acc, _ = Accumulator.load(path)
        except (ValueError, KeyError, OSError, zipfile.BadZipFile):  # a checkpoint of an older lensmount: the images still compare
            return np.zeros(shape)
        if acc.sum_image.shape == shape:
            return acc.std_error_image
    return np.zeros(shape)


def _extent(run: Run, shape) -> tuple[float, float, float, float]:
    det = run.summary.get("detector")
    if det:
        return (-det["width_mm"] / 2, det["width_mm"] / 2, -det["height_mm"] / 2, det["height_mm"] / 2)
    ny, nx = shape
    return (-nx / 2, nx / 2, -ny / 2, ny / 2)


def write_comparison(out: Path, old: Run, new: Run, result: CompareResult) -> dict[str, Path]:
    """difference.exr (Y = new − old, channels old and new), old.png and new.png on one colour scale,
    difference.png (signed scale), compare.json and report.html."""
    from lensmount.run.report import comparison_report, write_report
    from lensmount.run.results import read_exr, shared_scale, write_difference, write_exr, write_preview, write_summary

    a = read_exr(old.folder / "irradiance.exr", old.summary.get("files", {}).get("irradiance.exr"))["Y"]
    b = read_exr(new.folder / "irradiance.exr", new.summary.get("files", {}).get("irradiance.exr"))["Y"]
    a, b = a.astype(np.float64), b.astype(np.float64)
    if a.shape != b.shape or (old.summary.get("detector") or new.summary.get("detector")) and \
            old.summary.get("detector") != new.summary.get("detector"):
        raise InputError(f"the detectors differ: {a.shape[1]}×{a.shape[0]} pixels "
                         f"{old.summary.get('detector') or ''} vs {b.shape[1]}×{b.shape[0]} pixels "
                         f"{new.summary.get('detector') or ''}", file=str(new.folder), field="detector",
                         valid="two runs with the same detector (size and pixels)")
    paths = {"exr": out / "difference.exr", "png": out / "difference.png", "old_png": out / "old.png",
             "new_png": out / "new.png", "json": out / "compare.json", "html": out / "report.html"}
    scale = shared_scale([(a, _std_error_image(old, a.shape)), (b, _std_error_image(new, b.shape))])
    extent = _extent(new, b.shape)
    write_exr(paths["exr"], b - a, np.stack([a, b]), ["old", "new"], only_contributing=False)
    write_preview(paths["old_png"], a, extent, title=f"old: {old.folder.name}", scale=scale)
    write_preview(paths["new_png"], b, extent, title=f"new: {new.folder.name}", scale=scale)
    write_difference(paths["png"], b, a, extent, scale, title=f"{result.metric}: {result.verdict.verdict}")
    write_summary(paths["json"], result.to_dict())
    v = result.verdict
    kind = {"regression": "regression", "undecided": "undecided"}.get(v.verdict, "ok")
    headers = ["", "old", "new", "change", "interval of the change", "verdict"]
    rows = [["total", *verdict_row(v)]] + [[k, *verdict_row(pv)] for k, pv in result.per_part.items()
                                           if pv.old or pv.new]
    write_report(paths["html"], comparison_report(
        old.summary, new.summary, verdict_sentence(v), rows, headers,
        {"old": paths["old_png"], "new": paths["new_png"], "new − old": paths["png"]}, v.note, kind))
    return paths


def verdict_row(v: Verdict) -> list[str]:
    """old, new, change (relative), interval, verdict — as `compare` prints them."""
    rel = f" ({100 * v.relative_change:+.1f} %)" if v.relative_change is not None else ""
    interval = f"[{v.low:+.3g}, {v.high:+.3g}]" if math.isfinite(v.low) else "unknown"
    return [f"{v.old:.4g}", f"{v.new:.4g}", f"{v.change:+.3g}{rel}", interval, v.verdict]


def verdict_sentence(v: Verdict) -> str:
    rel = f" ({100 * v.relative_change:+.1f} %)" if v.relative_change is not None else ""
    return f"{v.verdict}: change {v.change:+.3g}{rel}, interval [{v.low:+.3g}, {v.high:+.3g}] at " \
           f"{100 * v.confidence:g} % confidence, tolerance {v.threshold:.3g}"


__all__ = ["CompareOptions", "CompareResult", "Run", "compare", "current_run", "stored_run", "check_comparable",
           "verdict_row", "verdict_sentence", "METRICS"]
