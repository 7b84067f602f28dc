"""`simulate`: design folder + scene → geometry (cached) → passes → results → store.

The CLI parses options into `SimulateOptions`, calls `simulate` and prints; a script
does the same. What happens on the way is told to an `Observer` (stages of the
build, CAD progress, each merged pass with its current value, error and ETA).
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from lensmount.analysis.passes import Accumulator
from lensmount.analysis.paths import face_areas, face_report, ghost_pairs, scene_tags, top_paths, write_paths
from lensmount.analysis.summary import build_summary
from lensmount.errors import InputError, WorkersGone
from lensmount.integrators.estimate import film_channels
from lensmount.integrators.plan import plan
from lensmount.integrators.registry import check_method
from lensmount.integrators.settings import EstimatorSettings
from lensmount.run.executor import WORKER_WAIT_S, executor_for, local_cluster_size
from lensmount.run.signals import Terminated, deferred, signal_name, stop_on_signals
from lensmount.loop.prepare import build, read_inputs, scene_file
from lensmount.loop.progress import PassStatus, forecast, status_of
from lensmount.loop.provenance import (collect, condition_changes, condition_sha256, design_changes, file_sha256,
                                      input_files, user_files)
from lensmount.optics.realrays import image_height
from lensmount.run.results import read_summary, write_run
from lensmount.run.runner import PassJob, Runner, Stopping, default_workers
from lensmount.run.store import Store, default_path
from lensmount.scene.scene import EFFECT_NAMES

# What the plan's per-phase seconds are: each pass times its own phases, and passes run side by side
TIME_SUMMED = "passes and workers: the seconds each pass spent, added up (more than the wall time on several workers)"
CHECKPOINT = "checkpoint.npz"
PATHS = "paths.npz"  # per-path and per-face sums for `lensmount paths` (analysis.paths.write_paths)


@dataclass(frozen=True)
class SimulateOptions:
    """One simulation. Unset stopping rules fall back to the scene's [run] table.

    design : design folder; scene : scene file
    out : results folder (default out/<scene name>)
    geometry : regenerate's output folder to reuse (default DESIGN/build, as `lensmount regenerate`)
    store : results store (default: lensmount.run.store.default_path); record : add the run to it
    argv : the command line recorded in the provenance (default sys.argv)
    scheduler, cluster : run the passes on a Dask cluster (an address, or "local:N"); see lensmount.run.executor
    worker_wait_s : with no Dask worker left, wait this long for one, then stop with the checkpoint (exit 75)
    quick : the QUICK preset instead of the scene's [run] rules (see `stopping`)
    """

    design: Path
    scene: Path
    method: str = "bidirectional"
    seed: int | None = None
    out: Path | None = None
    photons: int | None = None
    time_s: float | None = None
    target_rel_error: float | None = None
    passes: int | None = None
    photons_per_pass: int | None = None
    samples_per_pixel: int = 1
    view_map_pitch: int | None = None
    alpha: float = 0.7
    workers: int = 0
    resume: bool = False
    geometry: Path | None = None
    store: Path | None = None
    record: bool = True
    argv: list[str] | None = None
    scheduler: str | None = None
    cluster: str | None = None
    worker_wait_s: float = WORKER_WAIT_S
    quick: bool = False


@dataclass(frozen=True)
class Preset:
    """A stopping rule by name: the target error, the time cap and the fewest passes that may stop."""

    target_rel_error: float
    time_s: float
    min_passes: int


# For iteration: a first number with an honest error bar within half a minute of tracing. Only the run's
# length differs from the scene's rules (photons per pass, seed, estimator unchanged), so a quick run is the
# first passes of the full one: the same test condition and input hash in the store and `compare` (whose
# interval widens with its fewer passes), and `--resume` without --quick continues it to the scene's target.
QUICK = Preset(target_rel_error=0.10, time_s=30.0, min_passes=4)
ERROR_BAR_PASSES = 3  # the fewest passes with a standard error (analysis.passes)


def stopping(o: SimulateOptions, run) -> Stopping:
    """When the run stops. Rules set on the command line (photons, time, target, passes) replace the
    scene's; none set: the QUICK preset (o.quick) or the scene's [run] table (run: its RunSpec), its
    target error after the minimum passes, capped by its time_s and its passes."""
    least = QUICK.min_passes if o.quick else Stopping.min_passes
    if any(v is not None for v in (o.photons, o.time_s, o.target_rel_error, o.passes)):
        return Stopping(photons=o.photons, time_s=o.time_s, target_rel_error=o.target_rel_error,
                        max_passes=o.passes or 10_000, min_passes=least)
    # a cap stops no run before it has an error bar: a loaded machine's 30 s held one pass, which no
    # verdict can use (compare --until-decided then started the run again for its third)
    if o.quick:
        return Stopping(time_s=QUICK.time_s, target_rel_error=QUICK.target_rel_error, max_passes=run.passes,
                        min_passes=least, time_after_passes=ERROR_BAR_PASSES)
    return Stopping(time_s=run.time_s, target_rel_error=run.target_rel_error, max_passes=run.passes,
                    time_after_passes=ERROR_BAR_PASSES)


class Observer:
    """What `simulate` tells while it works; every method is optional (no-op here)."""

    def stage(self, text: str) -> None:
        """A step begins: resolving inputs, building the mount, building the scene, tracing."""

    def build_step(self, step: str, done: int, total: int) -> None:
        """CAD progress (lensmount.cad.regenerate's steps)."""

    def pass_done(self, status: PassStatus) -> None:
        """A pass was merged."""


@dataclass
class SimulateResult:
    out: Path
    summary: dict
    paths: dict[str, Path]
    interrupted: bool
    terminated: bool = False  # stopped by SIGTERM (a batch scheduler) rather than Ctrl-C
    run_id: int | None = None
    store_path: Path | None = None
    warnings: list[str] = field(default_factory=list)
    complete: bool = False  # the signal came after the last pass, while the results were written
    workers_gone: str | None = None  # stopped because no Dask worker came back in time: why
    stopped_short: str | None = None  # a cap (time, passes) stopped it before its target error: what it reached

    @property
    def exit_code(self) -> int:
        """0, 130 (SIGINT), 143 (SIGTERM) or 75 (no Dask worker: retry later, with --resume)."""
        if not self.interrupted:
            return 0
        return WorkersGone.EXIT_CODE if self.workers_gone else (143 if self.terminated else 130)

    def stop_message(self, then: str = "continue with the same command and --resume") -> str:
        """One line for a stopped run: what is kept and how to continue (`then`)."""
        how = self.workers_gone or ("SIGTERM" if self.terminated else "SIGINT")
        passes = self.summary.get("passes", 0)
        if self.complete:
            return f"{how} after the run was complete ({passes} passes): results written, nothing to continue"
        return f"{how}: stopped after {passes} passes; results and checkpoint written in {self.out}; {then}"

    def raise_if_stopped(self, then: str) -> None:
        """For callers with more work after this run (sweep, compare, converge): a stopped run stops
        them too, with this run's line and `then`, what to do about the caller's own work."""
        if self.workers_gone:
            raise WorkersGone(self.stop_message(then))
        if self.interrupted:
            raise (Terminated if self.terminated else KeyboardInterrupt)(self.stop_message(then))


def check_options(o: SimulateOptions) -> None:
    """Refuse bad options before anything is built or written."""
    check_method(o.method)
    if not 0.0 < o.alpha < 1.0:
        raise InputError(f"alpha = {o.alpha:g} is out of range", field="--alpha", valid="0 < alpha < 1")
    for name, value in (("--photons", o.photons), ("--passes", o.passes), ("--photons-per-pass", o.photons_per_pass)):
        if value is not None and value < 1:
            raise InputError(f"{name} must be at least 1, got {value}", field=name, valid="a positive integer")
    if o.time_s is not None and not (o.time_s > 0 and math.isfinite(o.time_s)):
        raise InputError(f"--time must be a positive number of seconds, got {o.time_s:g}", field="--time",
                         valid="a number of seconds > 0, e.g. --time 60")
    if o.workers < 0:
        raise InputError(f"--workers must not be negative, got {o.workers}", field="--workers",
                         valid="0 (one worker per core) or a positive number of processes")
    if o.target_rel_error is not None and not o.target_rel_error > 0:
        raise InputError("the target relative error must be positive", field="--target-rel-error",
                         valid="a number > 0, e.g. 0.05")
    if o.samples_per_pixel < 1:
        raise InputError("need at least one sample per pixel", field="--samples-per-pixel", valid="an integer ≥ 1")
    if o.view_map_pitch is not None and o.view_map_pitch < 1:
        raise InputError(f"--view-map-pitch must be at least 1, got {o.view_map_pitch}", field="--view-map-pitch",
                         valid="an integer ≥ 1 (pixels: 1 samples every pixel each pass)")
    if o.seed is not None and o.seed < 0:
        raise InputError(f"--seed must not be negative, got {o.seed}", field="--seed", valid="an integer ≥ 0")
    if o.cluster is not None:
        local_cluster_size(o.cluster)
    if not (o.worker_wait_s >= 0 and math.isfinite(o.worker_wait_s)):
        raise InputError(f"--worker-wait must be a number of seconds >= 0, got {o.worker_wait_s:g}",
                         field="--worker-wait", valid="seconds >= 0, e.g. --worker-wait 600")
    if o.scheduler is not None and o.cluster is not None:
        raise InputError("give either a scheduler address or a local cluster, not both", field="--cluster",
                         valid="--scheduler ADDRESS (or LENSMOUNT_SCHEDULER) | --cluster local:N")


def check_writable(folder: Path, field: str = "--out") -> None:
    """The results folder takes files, or the nearest folder that exists above it does (it is made
    when the first result is written): checked before a long build, and leaving nothing behind,
    so a run refused later (a bad scene, no checkpoint) has not made an empty folder."""
    existing = Path(folder).absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    try:
        if not existing.is_dir():
            raise NotADirectoryError(f"{existing} is a file, not a folder")
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".lensmount-write-test.")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(f"cannot write results there ({exc.strerror or exc})", file=str(folder), field=field,
                         valid="a folder you can write to (or one that can be created)") from None


def input_hash(design, spec, **params) -> str:
    """What a run's numbers depend on besides its seed and length: the CAD inputs
    (design.input_hash), the design's finishes.toml and user files, the test condition (the
    scene's source, detector, effects and objects, not its run length) and the estimator's
    parameters. Runs with equal hashes differ only by noise; a longer run of the same design and
    test condition has the same hash, so the store finds it whatever its length."""
    h = hashlib.sha256()
    h.update(design.input_hash.encode())
    for path in ([design.finishes_path] if design.finishes_path else []) + user_files(design):
        h.update(f"{path.name} {file_sha256(path)}\n".encode())
    h.update(condition_sha256(spec).encode())
    for k in sorted(params):
        h.update(f"{k}={params[k]!r}".encode())
    return h.hexdigest()[:16]


def planned_input_hash(o: SimulateOptions, design, spec) -> str:
    """The input hash a run with these options would get (design: loaded Design, spec: its SceneSpec
    with the detector fitted)."""
    return input_hash(design, spec, method=o.method, estimator_settings=estimator_settings(o, spec.run).as_dict())


def estimator_settings(o: SimulateOptions, run):
    """The estimator's knobs these options and the scene's [run] table (run: its RunSpec) set (the rest
    at their defaults)."""
    pitch = run.view_map_pitch if o.view_map_pitch is None else o.view_map_pitch
    return EstimatorSettings(samples_per_pixel=o.samples_per_pixel, view_map_pitch=pitch, alpha=o.alpha)


RESUME_KEYS = ("seed", "method", "input_hash", "photons_per_pass")  # what a resumed run must share


def _checkpoint_mismatch(meta: dict, asked: dict, checkpoint: Path, provenance, settings: dict) -> None:
    """InputError when the checkpoint is another run's: what differs, in the engineer's words where the run
    it belongs to left its summary.json beside it (which file and key of the inputs changed), else its keys."""
    differ = [k for k in RESUME_KEYS if str(meta.get(k)) != str(asked[k])]
    if not differ:
        return
    said = [f"{k} {meta.get(k)} -> {asked[k]}" for k in differ if k != "input_hash"]
    if "input_hash" in differ:
        said += _inputs_changed(checkpoint.parent / "summary.json", meta, provenance, settings)
    raise InputError(f"the checkpoint belongs to another run, of other inputs: {'; '.join(said)}",
                     file=str(checkpoint), field=differ[0],
                     valid="resume with the checkpoint's --seed, --method and --photons-per-pass on unchanged "
                           "inputs (undo the changes above), or run without --resume into another --out")


def _inputs_changed(summary_path: Path, meta: dict, provenance, settings: dict) -> list[str]:
    """What changed in the inputs since the run whose summary.json lies beside its checkpoint: design (file and
    key), test condition, estimator settings; its input hash when the summary cannot tell."""
    try:
        old = read_summary(summary_path)
    except InputError:  # no summary (the run never finished a pass's write) or a damaged one
        old = {}
    if old.get("input_hash") != meta.get("input_hash"):
        return [f"its input hash {meta.get('input_hash')} (no summary.json of that run beside it to say more)"]
    prov = old.get("provenance", {})
    lines = design_changes(prov.get("design", {}), provenance.design)
    lines += [f"scene {line}" for line in condition_changes(prov.get("condition", {}), provenance.condition)]
    was = old.get("estimator_settings", {})
    lines += [f"estimator {k}: {was.get(k)} -> {v}" for k, v in settings.items() if was.get(k) != v]
    return lines or ["the inputs hash differently, though no recorded file or key differs (another lensmount "
                     f"version: {prov.get('lensmount_version')} then)"]


def simulate(options: SimulateOptions, observer: Observer | None = None) -> SimulateResult:
    """Run one simulation end to end (see the module docstring). InputError on bad input,
    raised before anything is built or written.

    SIGINT or SIGTERM at any moment: once a pass is complete, the checkpoint and the results
    of the passes merged so far are written and the result says `interrupted`; before that,
    nothing is written and KeyboardInterrupt (`Terminated` for SIGTERM) is raised with a line
    saying so (lensmount.run.signals)."""
    with stop_on_signals():
        try:
            return _simulate(options, observer or Observer())
        except KeyboardInterrupt as stop:
            if stop.args:  # already says what happened
                raise
            raise type(stop)(f"{signal_name(stop)} before the first pass was complete: nothing written (a checkpoint "
                             "already there is as it was); run the same command again, with --resume or without"
                             ) from None


def _simulate(o: SimulateOptions, obs: Observer) -> SimulateResult:
    check_options(o)
    clock, wall = time.perf_counter(), {}  # the driver's phases in wall-clock seconds (the plan's are summed)
    scene_path = scene_file(o.design, o.scene)
    design, spec = read_inputs(o.design, scene_path, obs.stage)
    out = Path(o.out) if o.out is not None else Path("out") / scene_path.stem
    check_writable(out)
    seed = spec.run.seed if o.seed is None else o.seed
    per_pass = o.photons_per_pass or spec.run.photons
    settings = estimator_settings(o, spec.run)
    digest = planned_input_hash(o, design, spec)
    checkpoint = out / CHECKPOINT
    acc = None
    if o.resume and not checkpoint.exists():  # a run stopped before its first pass kept nothing: a retry starts it
        obs.stage(f"no checkpoint in {out}: nothing to resume, the run starts at its first pass")
    provenance = collect(design, spec, scene_path, o.argv)
    if o.resume and checkpoint.exists():
        acc, meta = Accumulator.load(checkpoint)  # a damaged one, or another version's: an InputError naming it
        _checkpoint_mismatch(meta, {"seed": seed, "method": o.method, "input_hash": digest,
                                    "photons_per_pass": per_pass}, checkpoint, provenance, settings.as_dict())
    if o.record:  # a locked or damaged store is said now, not after the run
        Store(default_path(design.root, o.store)).close()
    # the run's own copy of its inputs, as read now (the folder may change while it runs): kept in the store
    # with its row, so the run can be continued after the folder moved on
    inputs = read_inputs_kept(input_files(design, scene_path, spec)[0], provenance.inputs) if o.record else {}

    wall["reading the inputs"] = time.perf_counter() - clock
    prepared = build(design, spec, o.geometry, obs.stage, obs.build_step)
    wall["geometry and scene"] = time.perf_counter() - clock - sum(wall.values())
    return _run(o, obs, prepared, out, seed, per_pass, settings, digest, acc, provenance, wall, inputs)


def read_inputs_kept(files: dict[str, Path], sha256: dict[str, str]) -> dict[str, bytes]:
    """The input files' bytes by SHA-256, those that still hold what the provenance recorded."""
    contents = {}
    for name, path in files.items():
        data = path.read_bytes()
        if hashlib.sha256(data).hexdigest() == sha256.get(name):
            contents[sha256[name]] = data
    return contents


def _run(o, obs, prepared, out, seed, per_pass, settings, digest, acc, provenance, wall, inputs):
    design, spec, sc = prepared.design, prepared.spec, prepared.scene
    # legal but suspicious inputs (scene.build), and what the lens import changed (design.edges)
    warnings: list[str] = list(sc.warnings) + [f"lens: {w}" for w in design.lens_warnings]

    rule = stopping(o, spec.run)
    target = rule.target_rel_error

    work = plan(sc, settings)  # what is traced and what is skipped (integrators.plan); its scene is what the passes trace
    obs.stage("plan: " + "; ".join(f"{d.what} {'yes' if d.ran else 'skipped'}" for d in work.decisions))
    if acc is None:
        names = film_channels(sc)
        acc = Accumulator.empty((sc.detector.ny, sc.detector.nx), names, sc.detector.pixel_area)

    def job(i: int) -> PassJob:
        return PassJob(o.method, per_pass, seed, i, settings)

    effects = {k: bool(getattr(sc.effects, k)) for k in EFFECT_NAMES}
    # Flux entering the aperture per unit E_sun: the pupil times the irradiance that crosses the
    # entrance plane (exactly 0 once the whole source is behind it, with the reason said).
    aperture = sc.entrance_pupil_area_mm2 * sc.source.entering_fraction
    no_light = sc.source.no_light_enters
    if no_light:
        obs.stage(f"no light enters: {no_light}")
    executor = executor_for(workers=o.workers or default_workers(), scheduler=o.scheduler, cluster=o.cluster,
                            worker_wait_s=o.worker_wait_s, say=obs.stage)
    shown_max = rule.max_passes if (rule.photons is None and rule.time_s is None and target is None) else None
    history: list[tuple[float, float]] = []

    def progress(a, elapsed):
        obs.pass_done(status_of(a, elapsed, aperture, target, shown_max, history, rule.min_passes))

    obs.stage(forecast(rule, per_pass, stored_like(o, design, spec, digest), acc.n))
    obs.stage(f"tracing: {o.method}, {per_pass:,} photons per pass, on {executor.description}")
    runner = Runner(work.scene, job, acc, executor=executor, checkpoint=out / CHECKPOINT,
                    checkpoint_meta={"seed": seed, "input_hash": digest, "method": o.method,
                                     "photons_per_pass": per_pass}, progress=progress)
    start = time.perf_counter()
    runner.run(rule)
    wall["passes"] = time.perf_counter() - start
    if acc.n == 0:  # stopped before the first pass: nothing to write
        if runner.workers_gone:
            raise WorkersGone(f"{runner.workers_gone}: stopped before the first pass was complete, nothing written; "
                              "start workers and run the same command again")
        raise (Terminated if runner.terminated else KeyboardInterrupt)()
    try:
        with deferred():  # a signal now waits until the results are whole
            result = _write(o, prepared, out, acc, runner, executor, work, aperture, warnings, provenance, inputs,
                            seed=seed, photons_per_pass=per_pass, input_hash=digest, settings=settings,
                            no_light_enters=no_light, effects=effects, wall=wall)
    except KeyboardInterrupt as stop:  # it came while they were written: `result` is bound, the files whole
        if not result.interrupted:
            result.interrupted, result.terminated, result.complete = True, isinstance(stop, Terminated), True
    result.workers_gone = runner.workers_gone
    rel = result.summary.get("stray_fraction_rel_error")
    if target is not None and not runner.interrupted and rel is not None and rel > target:
        caps = f"{rule.max_passes} passes" + (f", {rule.time_s:.0f} s" if rule.time_s is not None else "")
        result.stopped_short = (f"stopped at {100 * rel:.2f} % before the target {100 * target:g} % ({acc.n} passes, "
                                f"{runner.elapsed:.0f} s; caps: {caps}): --resume with a longer --time or more "
                                "--passes continues it")
    return result


def stored_like(o: SimulateOptions, design, spec, digest: str) -> list:
    """Stored runs to foresee this one's time by: of the same inputs, else of the same scene and test
    condition on this design (another revision), newest last; none when there is no store yet."""
    path = default_path(design.root, o.store)
    if not path.is_file():
        return []
    with Store(path) as store:
        same = store.runs(input_hash=digest)
        return same or store.runs(design_path=design.root, scene_name=Path(o.scene).stem,
                                  condition_sha256=condition_sha256(spec))


def _write(o, prepared, out, acc, runner, executor, work, aperture, warnings, provenance, inputs, *, seed,
           photons_per_pass, input_hash, settings, no_light_enters, effects, wall) -> SimulateResult:
    """summary.json, the images, paths.npz and the store's row of a run that has passes."""
    design, built, sc = prepared.design, prepared.built, prepared.scene
    tags, areas = scene_tags(sc), face_areas(sc.mesh)
    summary = build_summary(acc, method=o.method, seed=seed, effects_ran=[k for k, v in effects.items() if v],
                            effects_skipped=[k for k, v in effects.items() if not v], time_s=runner.elapsed,
                            aperture_flux_mm2=aperture, input_hash=input_hash, estimator_settings=settings.as_dict(),
                            tag_table=tags,
                            extra={"photons_per_pass": photons_per_pass, "alpha": o.alpha, "workers": executor.workers,
                                   "provenance": provenance.to_dict(), "warnings": warnings,
                                   "no_light_enters": no_light_enters,
                                   "plan": {**work.as_dict(acc.diagnostics), "time_s_summed_over": TIME_SUMMED,
                                            "wall_time_s": {k: round(v, 3) for k, v in wall.items()}},
                                   "top_paths": top_paths(acc.paths, tags, aperture),
                                   "ghost_pairs": ghost_pairs(acc.paths, aperture),
                                   "faces": face_report(acc.paths, tags, areas, aperture),
                                   **({"units": OBJECT_SOURCE_UNITS} if not sc.source.at_infinity else {}),
                                   "geometry": str(built.folder.resolve()),
                                   "parts": sc.mesh.part_extents(),  # what `compare` matches parts by
                                   "detector": {"width_mm": sc.detector.width, "height_mm": sc.detector.height,
                                                "nx": sc.detector.nx, "ny": sc.detector.ny}})
    det = sc.detector
    paths = write_run(out, acc, summary, extent_mm=(-det.width / 2, det.width / 2, -det.height / 2, det.height / 2),
                      field_radius_mm=_field_radius(design.prescription))
    paths["paths"] = out / PATHS
    write_paths(paths["paths"], acc.paths, tags, areas, aperture, (-det.width / 2, det.width / 2, -det.height / 2, det.height / 2))
    result = SimulateResult(out, summary, paths, runner.interrupted, runner.terminated, warnings=warnings)
    if o.record and not runner.interrupted:
        result.store_path = default_path(design.root, o.store)
        with Store(result.store_path) as store:
            store.keep_inputs(inputs)
            result.run_id = store.record(summary, paths)
    return result


# A source at a finite distance is normalised to its own mean irradiance over the entrance pupil
# (physics.sources.ObjectSource), not to the sun's.
OBJECT_SOURCE_UNITS = {"irradiance": "E/E_ref (E_ref: the source's mean irradiance over the entrance pupil)",
                       "flux": "mm² (flux / E_ref)"}


def _field_radius(prescription) -> float | None:
    """Image height of the full field (the real chief ray's; finite objects included), for the preview outline."""
    r = image_height(prescription)
    return r if math.isfinite(r) and r > 0 else None


__all__ = ["QUICK", "Preset", "stopping", "stored_like", "SimulateOptions", "SimulateResult", "Observer", "simulate", "check_options", "input_hash",
           "planned_input_hash"]
