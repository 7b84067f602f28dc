"""Point source transmittance against off-axis angle.

PST(θ) = E_det(θ) / E_in(θ): the mean irradiance on the detector over the irradiance the
source puts on the entrance plane, E_sun cos θ. The runs give the detector irradiance
normalised by E_sun, so PST = mean(image) / cos θ, with the batch-means error of the
run carried through the same factor. Inside the field, with `direct` on, the direct image
dominates (PST of order the relative aperture area); past the field edge only stray light
is left and the curve drops by orders of magnitude.

What does not change with the source direction is built once: the mount geometry (the
regenerate cache), the Scene's mesh, optics, finishes and detector, each worker's tracer (an
Embree BVH; the workers live for the whole sweep) and, per pass, the bidirectional view map
(`Bidirectional.view_pass`: backward samples from the detector, which read no source, and the hit
points' search trees the gather reads). The
sweep runs pass-major: a job is pass i of every angle still running, one view map and then
each angle's photons gathered at it (`Bidirectional.photon_pass`, the scene with that angle's
source); each angle merges its passes in order into its own Accumulator and stops at its own
target, exactly where it would alone. What reads the source stays per angle: the emission,
the photons' aim at a diaphragm edge (its pilot, once per worker and angle), the ghost routes.

So an angle's value and error bar are those of a `simulate` of that angle with the same seed
(photon k of pass i and the backward samples of pass i are keyed by (seed, i) alone), and its
passes stay independent of one another: pass i and pass j see different view maps, so the
batch-means error bar holds. Different angles are correlated, though: angle a's pass i and
angle b's pass i gather at the same hit points, so their errors share the view map's part
(neighbouring points of the curve move together; a difference between two angles is not
as uncertain as their two error bars say).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable


from lensmount.analysis.passes import MIN_PASSES, TAIL_P, Accumulator
from lensmount.design.scene import RequirementSpec
from lensmount.errors import InputError
from lensmount.integrators.registry import SourceIndependentView, integrator
from lensmount.integrators.settings import EstimatorSettings
from lensmount.loop.prepare import build, read_inputs, scene_file
from lensmount.loop.provenance import collect
from lensmount.loop.simulate import SimulateOptions, check_options
from lensmount.run.runner import Runner, Stopping, default_workers
from lensmount.run.signals import Terminated
from lensmount.scene.scene import EFFECT_NAMES



ANGLES_VALID = ("ranges start:stop:step (stop included) and angles, separated by commas, in degrees from 0 to 90: "
                "e.g. 0:30:1,35:85:5 (fine near the field edge, coarse beyond) or 0,2,5,10")


def parse_angles(text: str) -> list[float]:
    """'0:30:1,35:85:5', '0,2,5,10' or any mix: ranges (start:stop:step, stop included) and single angles,
    in the order given, each angle once (its first place), each in [0°, 90°]."""
    field_name = "--angles"
    angles: list[float] = []
    try:
        for item in (s.strip() for s in text.split(",")):
            if not item:
                continue
            if ":" in item:
                start, stop, step = (float(v) for v in item.split(":"))
                if not step > 0 or stop < start:
                    raise ValueError
                n = int(math.floor((stop - start) / step + 1e-9)) + 1
                if n > 1000:
                    raise InputError(f"the range '{item}' holds {n} angles, more than a sweep needs",
                                     field=field_name, valid=ANGLES_VALID)
                angles += [round(start + i * step, 9) for i in range(n)]
            else:
                angles.append(float(item))
    except ValueError:
        raise InputError(f"cannot read the angles '{text}'", field=field_name, valid=ANGLES_VALID) from None
    if not angles or any(not (0.0 <= a <= 90.0) for a in angles):
        raise InputError(f"angles must lie in [0°, 90°], got '{text}'", field=field_name, valid=ANGLES_VALID)
    angles = list(dict.fromkeys(angles))
    if len(angles) > 1000:
        raise InputError(f"{len(angles)} angles is more than a sweep needs", field=field_name, valid=ANGLES_VALID)
    return angles


@dataclass(frozen=True)
class PstOptions:
    """A PST sweep. Per angle: passes of `photons_per_pass` until the PST has `target_rel_error`
    (std + bias; after 8 passes), at most `passes` (defaults: the scene's [run]; `passes` given
    without a target: that many passes, as before targets)."""

    design: Path
    scene: Path
    angles_deg: tuple[float, ...]
    azimuth_deg: float | None = None  # default: the scene's source azimuth
    method: str = "bidirectional"
    passes: int | None = None
    photons_per_pass: int | None = None
    seed: int | None = None
    samples_per_pixel: int = 1
    view_map_pitch: int | None = None  # default: the scene's run.view_map_pitch
    alpha: float = 0.7
    geometry: Path | None = None
    workers: int = 0  # processes running an angle's passes (0: one per core)
    target_rel_error: float | None = None


@dataclass(frozen=True)
class PstPoint:
    """One angle's PST; time_s: seconds into the sweep when its last pass was merged (the angles run
    together, pass by pass, so the time of one angle alone is not measured).

    std_error : 1σ, the passes' spread (batch means, × Student's t) plus the tail allowance of its terms
        (`analysis.passes.Tail`); None when the run cannot give one (`reason` says why)
    upper_bound : when nothing reached the detector in any pass, the 95 % upper bound on the PST (the rule of
        three: 3 photons' flux over the run, `Accumulator.no_signal_bound`); the PST then reads 0
    bias_bound : the kernel bias bound (bidirectional; 0 for forward), None when the ladder cannot bound it
    heavy : one pass dominates the others (`Tail.heavy`): the spread is not to be trusted
    reason : why std_error (or the bias bound) is missing or not to be trusted, in words; "" when all is there
    """

    angle_deg: float
    pst: float
    std_error: float | None
    in_field: bool
    passes: int
    photons: int
    time_s: float
    upper_bound: float | None = None
    bias_bound: float | None = 0.0
    heavy: bool = False
    reason: str = ""

    @property
    def error(self) -> float | None:
        """std_error + bias bound: the 1σ-scale half width a verdict is judged with (None when either is unknown)."""
        return None if self.std_error is None or self.bias_bound is None else self.std_error + self.bias_bound


@dataclass
class PstResult:
    points: list[PstPoint]
    field_edge_deg: float
    azimuth_deg: float
    method: str
    effects: list[str]
    provenance: dict = field(default_factory=dict)
    requirement: RequirementSpec | None = None


@dataclass(frozen=True)
class SourcesJob:
    """Pass `index` of every angle still running (`sources`: its place in the sweep → its Source), on
    one view map; picklable, as the runner's PassJob."""

    method: str
    photons: int
    seed: int
    index: int
    settings: EstimatorSettings
    sources: dict


SWEEP_PASS = "lensmount.loop.pst:sweep_pass"
_SCENES: dict = {}  # this worker's scene per angle for the run's scene (see `_with_source`)


def sweep_pass(scene, tracer, job: SourcesJob) -> dict:
    """In a worker: pass `job.index`'s view map once, then each angle's photons gathered at it; of each
    angle's pass, its totals ({place in the sweep: PassEstimate}). `tracer` is the base scene's: a
    tracer reads the mesh, the optics and the detector, never the source. An integrator without a
    source-independent view (`SourceIndependentView`) runs each angle's whole pass."""
    method = integrator(job.method, job.settings)
    if not isinstance(method, SourceIndependentView):
        return {k: method.run_pass(_with_source(scene, k, source), tracer, job.index, job.photons, job.seed).totals()
                for k, source in job.sources.items()}
    view = method.view_pass(scene, tracer, job.index, job.seed)
    return {k: method.photon_pass(_with_source(scene, k, source), tracer, view, job.index, job.photons,
                                  job.seed).totals()
            for k, source in job.sources.items()}


def _with_source(scene, k: int, source):
    """`scene` with angle k's source, the same object for every pass in this worker: the photons' pilot
    (`photon_target.edge_band`) is kept per scene, and would otherwise run again every pass."""
    if _SCENES.get("base") is not scene:  # a new sweep (holding the base keeps its id from being reused)
        _SCENES.clear()
        _SCENES["base"] = scene
    if k not in _SCENES:
        _SCENES[k] = dataclasses.replace(scene, source=source)
    return _SCENES[k]


class AngleTally:
    """The runner's accumulator for a sweep: each angle's Accumulator gets its own passes in order and
    stops by `stopping` as a run of that angle alone would; `running` are the angles not stopped yet
    (the next jobs carry only them), `stopped` those stopped, in the order they stopped. As a
    stopping rule (`done`) it holds when every angle has stopped."""

    def __init__(self, accumulators: list[Accumulator], stopping: Stopping):
        self.accumulators, self.stopping = accumulators, stopping
        self.running, self.stopped = list(range(len(accumulators))), []
        self.n, self.last_pass, self.elapsed_s = 0, -1, 0.0
        self.max_passes = stopping.max_passes

    def add(self, estimates: dict, pass_index: int) -> None:
        for k in self.running:
            self.accumulators[k].add(estimates[k], pass_index=pass_index)
        self.n, self.last_pass = self.n + 1, int(pass_index)
        done = [k for k in self.running if self.stopping.done(self.accumulators[k], self.elapsed_s)]
        self.running = [k for k in self.running if k not in done]
        self.stopped += done

    def done(self, _tally, _elapsed: float) -> bool:
        return not self.running


def pst_of(mean_flux_mm2: float, flux_std_error_mm2: float, detector_area_mm2: float, entering_fraction: float
           ) -> tuple[float, float | None]:
    """PST and its standard error from a run's mean detector flux (normalised by E_sun).

    entering_fraction : the source's irradiance on the entrance plane over E_sun (cos θ for a
        point source in front; exactly 0 from 90° on, so no light entering is PST 0, not 1/6e-17)."""
    cos = float(entering_fraction)
    scale = 1.0 / (detector_area_mm2 * cos) if detector_area_mm2 > 0 and cos > 0 else 0.0
    se = flux_std_error_mm2 * scale if math.isfinite(flux_std_error_mm2) else None
    return mean_flux_mm2 * scale, se


def point_of(acc: Accumulator, angle_deg: float, in_field: bool, detector_area_mm2: float, entering_fraction: float,
             time_s: float) -> PstPoint:
    """One angle's point from its run: PST, its error bar, or zero with its upper bound, and why not."""
    value, se = pst_of(acc.flux, acc.flux_std_error, detector_area_mm2, entering_fraction)
    scale = pst_of(1.0, 0.0, detector_area_mm2, entering_fraction)[0]
    tail, bias = acc.tail(), acc.bias_bound()[0]
    upper, reasons = None, []
    if scale == 0:
        se, reasons = None, ["the source lies at or beyond the entrance plane: no light enters, PST is not defined"]
    elif acc.upper_bound() is not None:
        lit = any(k.startswith("absorbed/") and v > 0 for k, v in acc.ledger.items())
        why = "lit faces sent none of it there" if lit else "no mechanical face is lit"
        upper, se = acc.no_signal_bound() * scale, None
        reasons.append(f"no light reached the detector ({why}): 0 below the 95 % upper bound from {acc.photons:,} "
                       "photons (3 photons' flux, the rule of three)")
    elif acc.n < MIN_PASSES:
        reasons.append(f"{acc.n} pass(es): an error bar needs {MIN_PASSES}")
    elif se is None:
        reasons.append(f"the terms the passes sum fall off as x^-{tail.index:.2f} with no bound: the run cannot bound "
                       "its error")
    if tail.heavy:
        reasons.append(f"pass {tail.largest_pass} dominates ({tail.over_median or 0:.3g}× the median, p = {tail.p:.2g} "
                       f"< {TAIL_P:g}): the spread is not to be trusted")
    bias_bound = None if bias.bound is None or not math.isfinite(bias.bound) else bias.bound * scale
    if bias.bound is None and upper is None:
        reasons.append(f"kernel bias not bounded: {bias.reason}")
    return PstPoint(float(angle_deg), value, se, in_field, acc.n, acc.photons, time_s, upper, bias_bound,
                    bool(tail.heavy), "; ".join(reasons))


def pst(options: PstOptions, progress: Callable[[str], None] | None = None) -> PstResult:
    """Run the sweep; progress(text) after each angle."""
    # lazy: keeps lensmount --help from loading scene.build and the BSDF models
    from lensmount.scene.build import make_source

    o = replace(options, scene=scene_file(options.design, options.scene))  # a file, or a scene's name
    say = progress or (lambda text: None)
    check_options(SimulateOptions(o.design, o.scene, method=o.method, seed=o.seed, passes=o.passes,
                                  target_rel_error=o.target_rel_error,
                                  photons_per_pass=o.photons_per_pass, samples_per_pixel=o.samples_per_pixel,
                                  view_map_pitch=o.view_map_pitch, alpha=o.alpha, geometry=o.geometry, workers=o.workers))
    design, spec = read_inputs(o.design, o.scene)
    if not spec.source.at_infinity:
        raise InputError(f"pst sweeps the angle of a source at infinity; this scene's source is a {spec.source.type} "
                         "at a finite distance", file=str(o.scene), field="source.type",
                         valid="a scene whose source is type = 'sun' or 'collimated'")
    seed = spec.run.seed if o.seed is None else o.seed
    passes = o.passes or spec.run.passes
    per_pass = o.photons_per_pass or spec.run.photons
    # an angle stops at its target: far outside the field few passes do, inside it many
    target = o.target_rel_error if o.target_rel_error is not None else (
        spec.run.target_rel_error if o.passes is None else None)
    azimuth = spec.source.azimuth_deg if o.azimuth_deg is None else float(o.azimuth_deg)
    provenance = collect(design, spec, o.scene).to_dict()

    base = build(design, spec, o.geometry, stage=say).scene
    det = base.detector
    area = det.width * det.height
    field_edge = float(design.prescription.max_field_deg)
    settings = EstimatorSettings(samples_per_pixel=o.samples_per_pixel, alpha=o.alpha,
                                 view_map_pitch=spec.run.view_map_pitch if o.view_map_pitch is None else o.view_map_pitch)
    sources = [make_source(spec.source.model_copy(update={"off_axis_deg": float(a), "azimuth_deg": azimuth}),
                           base.front_opening, base.mesh, det, design.prescription) for a in o.angles_deg]
    # Only each pass's totals travel and are kept (`PassEstimate.totals`): PST needs no image.
    names = integrator(o.method, settings).channels(base)
    tally = AngleTally([Accumulator.empty((1, 1), names, det.pixel_area) for _ in sources],
                       Stopping(target_rel_error=target, max_passes=passes))
    stopped: dict[int, PstPoint] = {}  # place in the sweep → its point, as the angles stop

    def job(index: int) -> SourcesJob:
        return SourcesJob(o.method, per_pass, seed, index, settings, {k: sources[k] for k in tally.running})

    def merged(_, elapsed: float) -> None:
        for k in tally.stopped:
            if k in stopped:
                continue
            angle = o.angles_deg[k]
            stopped[k] = p = point_of(tally.accumulators[k], angle, angle <= field_edge, area,
                                      sources[k].entering_fraction, elapsed)
            err = (f" ± {p.std_error:.2g}" if p.std_error is not None else
                   f" < {p.upper_bound:.2g} (95 %)" if p.upper_bound is not None else " (no error bar)")
            say(f"{angle:g}°: PST {p.pst:.4g}{err} ({'in' if p.in_field else 'outside'} the field, "
                f"{p.passes} passes, {elapsed:.1f} s into the sweep){'; ' + p.reason if p.reason else ''}")
        say(sweep_eta(tally, elapsed))

    workers = o.workers or default_workers()
    say(f"sweeping {len(sources)} angles: up to {passes} passes of {per_pass:,} photons each"
        f"{f', each angle stopping at {100 * target:g} %' if target else ''}, on {workers} worker(s); "
        "the first pass of every angle comes first (the estimate of the whole follows it)")
    runner = Runner(base, job, tally, workers=workers, progress=merged, run_pass_path=SWEEP_PASS, window=workers)
    runner.run(tally)
    if runner.interrupted:  # the sweep stops with the signal, as the passes did
        raise Terminated() if runner.terminated else KeyboardInterrupt()
    effects = [k for k in EFFECT_NAMES if getattr(base.effects, k)]
    return PstResult([stopped[k] for k in range(len(sources))], field_edge, azimuth, o.method, effects, provenance,
                     spec.requirement)


def sweep_eta(tally: AngleTally, elapsed: float) -> str:
    """A progress line after a merged pass: angles done, and the sweep's estimated total from the work so far (angle ×
    pass runs merged, at the same rate), at most every running angle to its last pass (angles that reach their
    target stop sooner)."""
    done = sum(acc.n for acc in tally.accumulators)
    left = sum(max(tally.max_passes - tally.accumulators[k].n, 0) for k in tally.running)
    total = elapsed * (done + left) / max(done, 1)
    return (f"pass {tally.last_pass + 1}: {len(tally.stopped)} of {len(tally.accumulators)} angles done, "
            f"{elapsed:.0f} s; the sweep ≤ {total:.0f} s in all (about {max(total - elapsed, 0):.0f} s left)")


__all__ = ["PstOptions", "PstPoint", "PstResult", "parse_angles", "point_of", "pst", "pst_of", "sweep_eta"]
