"""`compare`: two runs (result folders, or design folders simulated as needed) → verdict, difference image.

Runs are found in the results store by input hash: the design (lens, mount, finishes, user
files) and the test condition (the scene's source, detector, effects, objects), not the run
length, so a design state simulated before is not simulated again (any seed and length: equal
hashes differ only by noise). `plan` says which stored runs it takes, or what it must simulate
and about how long, before anything runs. Runs of different test conditions are refused;
between the same test condition on two designs the verdict comes with what changed in the
design, and parts in one run only are named added or removed, never judged.
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from lensmount.analysis.compare import UNDECIDED, Measurement, Verdict, judge, look_confidence, to_decide
from lensmount.analysis.error_bar import MIN_PASSES
from lensmount.analysis.part_match import match_parts
from lensmount.analysis.passes import Accumulator
from lensmount.errors import InputError
from lensmount.loop.prepare import read_inputs, scene_file
from lensmount.loop.progress import expected_s
from lensmount.loop.provenance import condition_changes, condition_sha256, design_changes, resolve_revision
from lensmount.loop.resume import continue_run, live_folder, not_resumable
from lensmount.loop.simulate import (CHECKPOINT, Observer, SimulateOptions, planned_input_hash, simulate, stopping,
                                    stored_like)
from lensmount.run.report import comparison_report, write_report
from lensmount.run.results import (
    read_exr, read_summary, shared_scale, write_difference, write_exr, write_preview, write_summary)
from lensmount.run.store import RunRecord, Store, default_path

METRICS = {  # metric -> (value key, std error key, bias bound key) in summary.json
    "stray_fraction": ("stray_fraction", "stray_fraction_std_error", "stray_fraction_bias_bound"),
    "stray_flux_mm2": ("stray_flux_mm2", "stray_flux_std_error_mm2", "stray_flux_bias_bound_mm2"),
}


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
        bound = self.no_signal_bound()
        if bound is not None and metric == "stray_flux_mm2":
            bound *= float(s.get("aperture_flux_mm2") or math.inf)
        passes = int(s.get("passes", 2))
        return Measurement(float(s[value]), _std_error(s.get(error), passes),
                           float(s.get(bias) or 0.0) if bias else 0.0, passes, int(s.get("photons", 0)),
                           float(s.get("time_s", 0.0)), bound, s.get("stray_fraction_bias_unbounded"))

    def no_signal_bound(self) -> float | None:
        """The stray fraction's 95 % bound for a figure that read zero in every pass (older summaries
        only hold it for an all-zero total, where it is looser)."""
        s = self.summary
        return s.get("stray_fraction_no_signal_bound", s.get("stray_fraction_upper_bound"))

    def part(self, name: str) -> Measurement:
        p = self.summary.get("per_part", {}).get(name, {"fraction": 0.0, "std_error": 0.0})
        passes = int(self.summary.get("passes", 2))
        return Measurement(float(p.get("fraction") or 0.0), _std_error(p.get("std_error"), passes),
                           float(p.get("bias_bound") or 0.0), passes, int(self.summary.get("photons", 0)),
                           float(self.summary.get("time_s", 0.0)), self.no_signal_bound(), p.get("bias_unbounded"))


def _std_error(stored: float | None, passes: int) -> float | None:
    """A summary's standard error: JSON holds no infinity, so a run of enough passes whose terms gave no
    error bar (`analysis.passes.Tail`) stored null; that is an unknown error (inf), not too few passes (None)."""
    return math.inf if stored is None and passes >= MIN_PASSES else stored


@dataclass(frozen=True)
class CompareOptions:
    """a, b : result folders, or design folders with `scene`; with `against` only `a` is given
    (a design folder) and the old run comes from the store: "last", "best" or a git revision.
    tolerance : relative to the old value; confidence : of the interval on the change.
    out : folder for difference.exr/png and compare.json (default NEW/compare).
    method, workers, passes, photons_per_pass, time_s, quick : for runs that must be simulated (unset:
        the scene's [run] table, or the QUICK preset); a stored run is reused when its input hash matches.
    until_decided : while the verdict is undecided, resume the runs by the passes that would decide
        it and look again, within `budget_s` seconds of further tracing (`compare_until_decided`)."""

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
    until_decided: bool = False
    budget_s: float = 3600.0
    quick: bool = False  # runs that must be simulated take the QUICK preset (loop.simulate)


@dataclass
class CompareResult:
    old: Run
    new: Run
    verdict: Verdict
    per_part: dict[str, Verdict]
    metric: str
    paths: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    design_changes: list[str] = field(default_factory=list)  # what changed in the design, in the engineer's words
    parts_added: dict[str, float] = field(default_factory=dict)  # part → its value, parts in the new run only
    parts_removed: dict[str, float] = field(default_factory=dict)  # part → its old value
    renamed: dict[str, str] = field(default_factory=dict)  # new name → the old revision's name of the same part
    stopped: str = ""  # why --until-decided stopped with the verdict undecided, and what would decide it

    @property
    def exit_code(self) -> int:
        """0: no significant regression (also undecided); 1: regression beyond the tolerance."""
        return 1 if self.verdict.regression else 0

    def to_dict(self) -> dict:
        def clean(v: Verdict) -> dict:
            return {k: (x if not isinstance(x, float) or math.isfinite(x) else None) for k, x in asdict(v).items()}

        return {"metric": self.metric, "old_run": str(self.old.folder.resolve()), "new_run": str(self.new.folder.resolve()),
                **clean(self.verdict), "per_part": {k: clean(v) for k, v in self.per_part.items()},
                "design_changes": self.design_changes, "parts_added": self.parts_added,
                "parts_removed": self.parts_removed, "renamed": self.renamed, "notes": self.notes, "exit_code": self.exit_code}


@dataclass(frozen=True)
class RunSource:
    """Where one side of a comparison comes from, known before anything runs: a result folder, a
    stored run (`record`), or a run to simulate (`simulate`, about `estimate_s` seconds at the
    speed of the store's runs of the scene; None when the store has none to go by)."""

    role: str  # "old" | "new"
    folder: Path
    record: RunRecord | None = None
    input_hash: str | None = None  # of a design folder's current state
    condition: str | None = None  # its test condition (provenance.condition_sha256)
    why: str = ""  # why this stored run: "same design and test condition", "best", "last", a revision
    simulate: SimulateOptions | None = None
    passes: int | None = None
    photons_per_pass: int | None = None
    estimate_s: float | None = None


def _stored_folder(record: RunRecord) -> Path:
    return Path(record.summary_path).parent


def _usable(runs: list[RunRecord]) -> list[RunRecord]:
    return [r for r in runs if Path(r.summary_path).is_file()]


def plan_current(design: Path, scene: str, o: CompareOptions, role: str = "new") -> RunSource:
    """The design folder's current state on `scene`: a stored run of the same design and test
    condition (any length, the longest), else the run to simulate and its estimated time."""
    scene_path = scene_file(design, scene)
    sim = SimulateOptions(design, scene_path, method=o.method, workers=o.workers, store=o.store, passes=o.passes,
                          photons_per_pass=o.photons_per_pass, time_s=o.time_s, quick=o.quick)
    loaded, spec = read_inputs(design, scene_path)
    digest = planned_input_hash(sim, loaded, spec)
    condition = condition_sha256(spec)
    with Store(default_path(design, o.store)) as store:
        stored = _usable(store.runs(input_hash=digest))
    if stored:
        best = max(stored, key=lambda r: (r.photons, r.id))  # the longest: the smallest error for the same inputs
        return RunSource(role, _stored_folder(best), best, digest, condition, "same design and test condition")
    rule = stopping(sim, spec.run)
    per_pass = o.photons_per_pass or spec.run.photons
    expected = expected_s(rule, per_pass, stored_like(sim, loaded, spec, digest))
    out = Path(design).resolve() / ".lensmount" / "runs" / f"{scene_path.stem}-{digest[:12]}"
    return RunSource(role, out, input_hash=digest, condition=condition, simulate=replace(sim, out=out),
                     passes=expected[1] if expected else rule.max_passes, photons_per_pass=per_pass,
                     estimate_s=expected[0] if expected else o.time_s)


def stored_run(design: Path, scene: str, against: str, new: RunSource, o: CompareOptions) -> RunSource:
    """The old run of `design` on `scene` from the store, of the new run's test condition: last (other
    inputs than the new run's), best, or a git revision."""
    scene_name = Path(scene).stem
    exclude_hash = new.input_hash
    with Store(default_path(design, o.store)) as store:
        every = _usable(store.runs(design_path=design, scene_name=scene_name))
        runs = _usable(store.runs(design_path=design, scene_name=scene_name, condition_sha256=new.condition))
    if not runs:
        other = f"; {len(every)} stored runs of it have another test condition (its source, detector, effects " \
                "or objects were changed since)" if every else ""
        raise InputError(f"no stored run of scene {scene_name!r} for this design and test condition{other}",
                         file=str(design), field="--against",
                         valid="simulate a revision first, or compare two result folders")
    pick: RunRecord | None
    if against == "last":
        others = [r for r in runs if r.input_hash != exclude_hash]
        pick = (others or runs)[-1]
    elif against == "best":
        pick = min((r for r in runs if r.stray_fraction is not None), key=lambda r: r.stray_fraction, default=None)
    else:  # a revision: git's name for it (HEAD~1, a tag) or a prefix of a stored commit id
        commit = resolve_revision(design, against) or against.lower()
        matches = [r for r in runs if r.git_commit and r.git_commit.startswith(commit)]
        pick = max(matches, key=lambda r: (not r.git_dirty, r.id)) if matches else None  # clean runs first
    if pick is None:
        commits = sorted({r.git_commit[:10] for r in runs if r.git_commit})
        raise InputError(f"no stored run matches {against!r}", file=str(design), field="--against",
                         valid="last, best, or a stored git revision: " + (", ".join(commits) or "(none stored)"))
    return RunSource("old", _stored_folder(pick), pick, pick.input_hash, pick.condition_sha256, against)


def plan(options: CompareOptions) -> tuple[RunSource, RunSource]:
    """(old, new): where each run comes from, before anything is simulated (InputError on bad options)."""
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
        new = plan_current(a, o.scene, o)
        return stored_run(a, o.scene, o.against, new, o), new
    if o.b is None:
        raise InputError("compare needs two runs", field="B",
                         valid="two result folders, two design folders with --scene, or one design with --against")
    b = Path(o.b)
    if (a / "summary.json").is_file() or (b / "summary.json").is_file():
        return RunSource("old", a), RunSource("new", b)
    if o.scene is None:
        raise InputError("design folders need --scene", field="--scene", valid="a scene name or file")
    return plan_current(a, o.scene, o, "old"), plan_current(b, o.scene, o, "new")


def obtain(source: RunSource, observer: Observer | None) -> Run:
    """The run a RunSource names: loaded, or simulated now."""
    if source.simulate is None:
        return Run.load(source.folder, "A" if source.role == "old" else "B")
    result = simulate(source.simulate, observer)
    result.raise_if_stopped("no comparison made: run the same compare again")
    return Run(result.out, result.summary)


def check_comparable(old: Run, new: Run, metric: str) -> list[str]:
    """InputError when the two runs do not measure the same thing; notes for harmless differences."""
    if metric not in METRICS:
        raise InputError(f"unknown metric {metric!r}", field="--metric", valid=", ".join(METRICS))
    po, pn = old.summary.get("provenance", {}), new.summary.get("provenance", {})
    if po.get("condition_sha256") and pn.get("condition_sha256"):
        if po["condition_sha256"] != pn["condition_sha256"]:
            differ = condition_changes(po.get("condition", {}), pn.get("condition", {}))
            raise InputError(f"the runs are of different test conditions ({'; '.join(differ) or 'the scenes differ'}; "
                             f"{po.get('scene_path')} vs {pn.get('scene_path')}): that is another test, not a "
                             "revision of the design", file=str(new.folder), field="scene",
                             valid="two runs of the same test condition (the scene's source, detector, effects and "
                                   "objects); the design (lens, mount, finishes, user files) and the run length "
                                   "may differ")
    elif po.get("scene_sha256") and pn.get("scene_sha256") and po["scene_sha256"] != pn["scene_sha256"]:
        raise InputError(f"the runs simulate different scenes ({po.get('scene_path')} vs {pn.get('scene_path')}; "
                         "the scene files differ, and a run recorded before test conditions were recorded apart "
                         "cannot tell a test change from a design change)", file=str(new.folder), field="scene",
                         valid="two runs of the same scene file, or runs of this lensmount version")
    notes = []
    if old.summary.get("method") != new.summary.get("method"):
        notes.append(f"methods differ: {old.summary.get('method')} (old) vs {new.summary.get('method')} (new)")
    if sorted(old.summary.get("effects", [])) != sorted(new.summary.get("effects", [])):
        raise InputError("the runs simulate different effects", file=str(new.folder), field="effects",
                         valid=f"the same effects as the old run: {', '.join(old.summary.get('effects', []))}")
    return notes


def compare(options: CompareOptions, observer: Observer | None = None,
            sources: tuple[RunSource, RunSource] | None = None, write: bool = True) -> CompareResult:
    """Compare two runs (see CompareOptions; `sources`: `plan(options)`, made here when not given);
    writes difference.exr, difference.png, compare.json and report.html (`write`: the looks of
    --until-decided before the last write nothing)."""
    o = options
    if o.until_decided:
        return compare_until_decided(o, observer, write)
    old_source, new_source = sources or plan(o)
    new = obtain(new_source, observer)
    old = obtain(old_source, observer)
    notes = check_comparable(old, new, o.metric)
    if old.folder.resolve() == new.folder.resolve():
        notes.append("old and new are the same stored run: the store holds no run of other inputs to compare with")
    verdict = judge(old.measurement(o.metric), new.measurement(o.metric), o.tolerance, o.confidence)
    result = CompareResult(old, new, verdict, {}, o.metric, notes=notes, design_changes=design_changes(
        old.summary.get("provenance", {}).get("design", {}), new.summary.get("provenance", {}).get("design", {})))
    if o.metric == "stray_fraction":
        old_parts, new_parts = old.summary.get("per_part", {}), new.summary.get("per_part", {})
        match = match_parts(old.summary.get("parts"), new.summary.get("parts"), list(old_parts), list(new_parts))
        for was, name in match.pairs:  # the same piece of metal, whatever its number in each revision
            if was in old_parts or name in new_parts:  # else it absorbs in both: zero by construction
                result.per_part[name] = judge(old.part(was), new.part(name), o.tolerance, o.confidence)
                if was != name:
                    result.renamed[name] = was
        # a part of one design only: named so, never judged (-100 % is no finding)
        result.parts_removed.update({name: old.part(name).value for name in match.removed})
        result.parts_added.update({name: new.part(name).value for name in match.added})
    if write:
        result.paths = write_comparison(comparison_folder(o, new), old, new, result)
    return result


def comparison_folder(o: CompareOptions, new: Run) -> Path:
    return Path(o.out) if o.out is not None else live_folder(new.folder, new.summary) / "compare"  # never into a store row's copy


MAX_LOOKS = 12  # looks of --until-decided: α · 6/(π² j²) leaves look 12 a 1/240 share of α


def compare_until_decided(options: CompareOptions, observer: Observer | None = None,
                          write: bool = True) -> CompareResult:
    """`compare`, then while the verdict is undecided: resume the runs by the passes that would decide
    it (`analysis.compare.to_decide`) and look again. Look j judges at `look_confidence(c, j)`, so the
    chance that any look reads a wrong verdict stays below 1 − c however many looks it takes. Stops at
    a verdict, when the next step would overrun `budget_s` seconds of tracing, when no number of passes
    would decide it, or after MAX_LOOKS looks; the notes say which. The last look's images and report are
    written once, at the end (`write`; False: by the caller, `write_comparison`, e.g. after it has said
    the verdict)."""
    o = replace(options, until_decided=False)
    if not o.budget_s >= 0:
        raise InputError(f"budget {o.budget_s:g} s is negative", field="--budget", valid="seconds ≥ 0, e.g. 3600")
    look, spent, steps, stopped = 1, 0.0, [], ""
    result = compare(replace(o, confidence=look_confidence(o.confidence, look)), observer, write=False)
    out = comparison_folder(o, result.new)  # where look 1 would have written: the new run's live folder
    while result.verdict.verdict == UNDECIDED and look < MAX_LOOKS:
        runs = (result.old, result.new)
        m = [r.measurement(o.metric) for r in runs]
        held = [not_resumable(r.folder, r.summary, o.store) for r in runs]
        grows = tuple(h is None for h in held)
        unknown = [x.std_error is not None and (bool(x.bias_unbounded) or not math.isfinite(x.std_error)) for x in m]
        would = "would decide it, if the change is as measured"
        if any(x.std_error is None for x in m):  # fewer than 3 passes: first an error bar
            more = tuple(max(3 - x.passes, 0) for x in m)
            more = None if any(a and not g for a, g in zip(more, grows)) else more
        elif any(u and g for u, g in zip(unknown, grows)):
            # an error not known at these passes (a kernel bias the ladder of radii cannot bound, terms too
            # heavy-tailed for an error bar): the ladder's shape test and the tail's end sharpen with passes,
            # so twice the passes may give it one; no promise, the budget and the looks bound the attempt
            more = tuple(x.passes if u and g else 0 for x, u, g in zip(m, unknown, grows))
            would = f"may give the run(s) an error bar ({result.verdict.note})"
        else:
            more = to_decide(*m, result.verdict.threshold, look_confidence(o.confidence, look + 1), grows)
        if more is None:
            why = "; ".join(f"the {n} run cannot take more passes: {h}" for n, h in zip(("old", "new"), held) if h)
            stopped = "no number of passes decides it: " + (why or result.verdict.note)
            break
        per_pass = [x.time_s / max(x.passes, 1) for x in m]
        cost = sum(a * t for a, t in zip(more, per_pass))
        if spent + cost > o.budget_s:  # the share of the step the budget still pays for, then a look
            share = tuple(int(a * (o.budget_s - spent) / cost) for a in more)
            if not any(share):
                stopped = (f"the budget is spent ({spent:.0f} of {o.budget_s:.0f} s): {_passes_of(more)} "
                           f"(~{cost:.0f} s at the runs' speed) {would}; --budget {math.ceil(spent + cost)} or more "
                           "would run them")
                break
            more = share
        resumed = [resume(r, a, o, observer) if a else r for r, a in zip(runs, more)]
        spent += sum(r.summary.get("time_s", 0.0) - x.time_s for r, x in zip(resumed, m))
        look += 1
        steps.append(f"look {look}: +{more[0]} passes of the old run, +{more[1]} of the new")
        # a look that is not the last writes no images (4 previews and an EXR a look, seconds each)
        result = compare(replace(o, a=resumed[0].folder, b=resumed[1].folder, against=None, scene=None,
                                 confidence=look_confidence(o.confidence, look), out=out), observer, write=False)
    if result.verdict.verdict == UNDECIDED and not stopped:
        stopped = f"stopped after {look} looks, the most --until-decided takes"
    result.stopped = stopped
    result.notes += steps + ([stopped] if stopped else []) + [f"until decided: {look} look(s), {spent:.0f} s of further tracing; look {look}'s "
                             f"interval at {100 * look_confidence(o.confidence, look):.4g} % so that all looks "
                             f"together keep {100 * o.confidence:g} %"]
    if write:
        result.paths = write_comparison(out, result.old, result.new, result)  # compare.json with the looks' notes
    return result


def _passes_of(more: tuple[int, int]) -> str:
    return " and ".join(f"{a} more pass{'es' if a != 1 else ''} of the {name} run"
                        for a, name in zip(more, ("old", "new")) if a)


def resume(run: Run, more: int, o: CompareOptions, observer: Observer | None = None) -> Run:
    """The run continued by `more` passes on the inputs it ran on (`loop.resume.continue_run`)."""
    result = continue_run(run.folder, run.summary, more, o.workers, o.store, observer)
    return Run(result.out, result.summary)


def _std_error_image(run: Run, shape) -> np.ndarray:
    """Per-pixel standard error from the run's checkpoint (the pass sums), zeros when it has none
    (or one this version cannot read): it only sets the preview's pixel binning."""
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
    rows = [["total", *verdict_row(v)]] + [[part_label(result, k), *verdict_row(pv)]
                                           for k, pv in result.per_part.items() if pv.old or pv.new] + part_rows(result)
    detail = " ".join(filter(None, [v.note, "Design changes: " + "; ".join(result.design_changes) + "."
                                    if result.design_changes else "Design: unchanged."]))
    write_report(paths["html"], comparison_report(
        old.summary, new.summary, verdict_sentence(v), rows, headers,
        {"old": paths["old_png"], "new": paths["new_png"], "new − old": paths["png"]}, detail, kind))
    return paths


def verdict_row(v: Verdict) -> list[str]:
    """old, new, change (relative), interval, verdict — as `compare` prints them."""
    rel = f" ({100 * v.relative_change:+.1f} %)" if v.relative_change is not None else ""
    interval = f"[{v.low:+.3g}, {v.high:+.3g}]" if math.isfinite(v.low) else "unknown"
    return [f"{v.old:.4g}", f"{v.new:.4g}", f"{v.change:+.3g}{rel}", interval, v.verdict]


def part_rows(result: CompareResult) -> list[list[str]]:
    """Rows for the parts of one run only (same columns as `verdict_row`): named added or removed."""
    return [[k, f"{x:.4g}", "—", "—", "—", "removed"] for k, x in result.parts_removed.items()] + \
           [[k, "—", f"{x:.4g}", "—", "—", "added"] for k, x in result.parts_added.items()]


def part_label(result: CompareResult, name: str) -> str:
    """A judged part's name, with the old revision's name for it when that differed ('vane-3 (was vane-5)')."""
    was = result.renamed.get(name)
    return f"{name} (was {was})" if was else name


def verdict_sentence(v: Verdict) -> str:
    rel = f" ({100 * v.relative_change:+.1f} %)" if v.relative_change is not None else ""
    return f"{v.verdict}: change {v.change:+.3g}{rel}, interval [{v.low:+.3g}, {v.high:+.3g}] at " \
           f"{100 * v.confidence:g} % confidence, tolerance {v.threshold:.3g}"


__all__ = ["CompareOptions", "CompareResult", "Run", "RunSource", "compare", "compare_until_decided", "resume", "obtain",
           "plan", "plan_current", "stored_run", "check_comparable", "comparison_folder", "write_comparison",
           "part_label", "part_rows", "verdict_row", "verdict_sentence", "METRICS"]
