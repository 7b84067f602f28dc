"""`optimize`: search the mount's keys for the lowest stray light, knowing the objective is noisy.

    optimize(OptimizeOptions(Path("mylens")))   # reads mylens/optimize.toml (loop.optimize_spec)

Each candidate is a design revision: a copy of the design folder with the variables' keys set
(`loop.sweep.write_variant`), regenerated (the CAD cache serves a layout built before), checked
against the constraints on the regenerated mesh, then simulated. The noise is handled on purpose:

- common random numbers: every candidate runs with the same simulation seed, so pass i of two
  candidates starts the same photons and a difference carries less noise than either value
  (measured once per study on the start and a nearby design: `CrnEffect`);
- a fidelity that grows: every candidate gets the first rung of passes; one not worse than the
  incumbent by more than one combined standard error at that rung earns the next;
- the incumbent re-evaluated: a challenger that beats it on the top rung is run to twice the top
  rung's passes, as the incumbent was, and replaces it only if still lower there;
- the final verdict: the best and the start simulated on a seed the search never used and judged
  by `compare` at the spec's confidence (99 % by default).

The search is Optuna's TPE. Its study lives in SQLite beside the run store; the sampler is seeded
per candidate from (sampler seed, candidate index), so a study stopped after k candidates and run
again ends where an uninterrupted one does.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lensmount.analysis.passes import Accumulator
from lensmount.atomic import write_text
from lensmount.design.folder import load_design
from lensmount.errors import InputError
from lensmount.loop.compare import CompareOptions, compare
from lensmount.loop.optimize_report import Candidate, CrnEffect, OptimizeResult, write_report
from lensmount.loop.optimize_spec import OptimizeSpec, Variable, load_optimize
from lensmount.loop.prepare import scene_file
from lensmount.loop.regenerate import RegenerateOptions, regenerate
from lensmount.loop.simulate import CHECKPOINT, Observer, SimulateOptions, simulate
from lensmount.loop.sweep import Param, write_variant
from lensmount.mesh import TaggedMesh
from lensmount.run.store import default_path

INFEASIBLE = 1.0  # told to the sampler for a candidate that cannot be built or breaks a constraint (with its flag)
CONTENDER_Z = 1.0  # a candidate within this many combined standard errors of the incumbent earns more passes


class OptimizeObserver(Observer):
    """What `optimize` tells besides simulate's stages and passes."""

    def candidate(self, done: int, total: int) -> None:
        """`done` of `total` candidates are evaluated (on a resume, those of earlier calls count)."""


@dataclass(frozen=True)
class OptimizeOptions:
    """design : the start design folder; spec : the optimize table (default DESIGN/optimize.toml);
    out : candidates, revisions and the report; trials : overrides the table's;
    budget : candidates this call evaluates at most (the study resumes from the store on the next call);
    store : the run store (the study sits beside it); method, workers : as simulate's."""

    design: Path
    spec: Path | None = None
    out: Path = Path("out/optimize")
    trials: int | None = None
    budget: int | None = None
    store: Path | None = None
    method: str = "bidirectional"
    workers: int = 0


class Search:
    """The evaluations of one study: the design, the scene and the spec's fidelity, common to every candidate."""

    def __init__(self, options: OptimizeOptions, spec: OptimizeSpec, obs: Observer):
        self.o, self.spec, self.obs = options, spec, obs
        self.design = Path(options.design)
        self.scene = scene_file(self.design, spec.objective.scene)
        self.params = tuple(Param("mount", tuple(key.split(".")), ()) for key in spec.variables)
        self.seed = spec.search.seed
        self.study = study_name(self.design, spec)
        self.store = default_path(self.design, options.store)  # the start design's: a revision's row goes there

    def candidate(self, index: int, values: dict, folder: Path) -> Candidate:
        """Write, regenerate and check one revision (no simulation yet). A folder another study or
        other values left there is cleared: its runs would resume on other inputs."""
        c = Candidate(index, values, folder)
        named = {f"mount.{k}": v for k, v in values.items()}
        mark = {"study": self.study, "values": values}
        if folder.exists() and _read_json(folder / "candidate.json") != mark:
            shutil.rmtree(folder)
        try:
            design, _ = write_variant(self.design, self.scene, folder, self.params, named)
            write_text(folder / "candidate.json", json.dumps(mark))
            regenerate(RegenerateOptions(design, out=folder / "build"))
        except InputError as error:  # the mount cannot be built from these values, or fails its checks
            c.feasible, c.why = False, error.paragraph()
            return c
        c.length_mm, c.outer_diameter_mm = extent(TaggedMesh.load(folder / "build" / "mesh.npz"))
        limits = self.spec.constraints
        broken = [f"{what} {got:.2f} mm > {most:g} mm" for what, got, most in (
            ("overall length", c.length_mm, limits.max_length_mm),
            ("outer diameter", c.outer_diameter_mm, limits.max_outer_diameter_mm)) if most is not None and got > most]
        if broken:
            c.feasible, c.why = False, "; ".join(broken)
        return c

    def run(self, c: Candidate, passes: int, seed: int | None = None, out: Path | None = None,
            record: bool = False) -> tuple[Path, int | None]:
        """Simulate candidate `c` to `passes` on `seed` (the search's by default), continuing its run
        when one is there; its value on the search's seed goes into c.runs."""
        seed = self.seed if seed is None else seed
        out = out or c.folder / "run"
        summary = out / "summary.json"
        done = json.loads(summary.read_text()).get("passes", 0) if summary.is_file() else 0
        run_id = None
        if done < passes:
            base = SimulateOptions(c.folder / "design", c.folder / self.scene.name, method=self.o.method, seed=seed,
                                   out=out, passes=passes, photons_per_pass=self.spec.fidelity.photons_per_pass,
                                   workers=self.o.workers, geometry=c.folder / "build", store=self.store,
                                   record=record, resume=(out / CHECKPOINT).is_file())
            result = simulate(base, self.obs)
            result.raise_if_stopped("the optimize study resumes where it stopped: run the same command again")
            run_id = result.run_id
        if seed == self.seed:  # from the passes themselves: the same rung reads the same after a resume
            c.runs[passes] = mean_and_error(per_pass_fraction(out)[:passes])
        return out, run_id


def _read_json(path: Path):
    return json.loads(path.read_text()) if path.is_file() else None


def extent(mesh: TaggedMesh) -> tuple[float, float]:
    """(overall length along the axis, outer diameter) of the regenerated mount, mm."""
    v = mesh.vertices
    return float(v[:, 2].max() - v[:, 2].min()), float(2 * np.hypot(v[:, 0], v[:, 1]).max())


def per_pass_fraction(run: Path) -> np.ndarray:
    """Each pass's stray fraction of a run (its checkpoint's fluxes over the aperture flux)."""
    acc, _ = Accumulator.load(run / CHECKPOINT)
    aperture = json.loads((run / "summary.json").read_text())["aperture_flux_mm2"]
    return np.asarray(acc.pass_flux) / aperture


def mean_and_error(series: np.ndarray) -> tuple[float, float]:
    """The mean of the passes and its standard error."""
    return float(series.mean()), float(series.std(ddof=1) / math.sqrt(len(series)))


def start_values(design: Path, variables: dict[str, Variable]) -> dict:
    """The start design's value of every variable (its mount.toml, else the key's default)."""
    mount = load_design(design).mount
    values = {}
    for key in variables:
        node = mount
        for part in key.split("."):
            node = node.get(part) if isinstance(node, dict) else getattr(node, part, None)
            if node is None:
                raise InputError(f"the mount has no key '{key}'", file=str(Path(design) / "mount.toml"),
                                 field=f"optimize.variables.{key}", valid="a key docs/mount-toml.md lists")
        values[key] = node
    return values


def nearby(values: dict, variables: dict[str, Variable]) -> dict:
    """The start with its first continuous variable moved by 1 % of its range (towards the middle)."""
    for key, var in variables.items():
        if var.finishes is None and not var.integer:
            step = 0.01 * (var.high - var.low) * (1 if values[key] < (var.low + var.high) / 2 else -1)
            return {**values, key: values[key] + step}
    raise InputError("measuring common random numbers needs a continuous variable", field="optimize.variables",
                     valid="at least one variable with low and high and no integer = true")


def crn_effect(search: Search, start: Candidate, out: Path, passes: int) -> CrnEffect:
    """Variance of the per-pass difference start − nearby on shared seeds against independent seeds."""
    values = nearby(start.values, search.spec.variables)
    near = search.candidate(-2, values, out / "crn-nearby")
    if not near.feasible:
        raise InputError(f"the design 1 % away from the start cannot be built: {near.why}",
                         field="optimize.variables", valid="bounds around a start that builds")
    a = per_pass_fraction(search.run(start, passes)[0])
    b = per_pass_fraction(search.run(near, passes)[0])
    c = per_pass_fraction(search.run(near, passes, seed=search.seed + 1, out=near.folder / "run-independent")[0])
    n = min(len(a), len(b), len(c))
    return CrnEffect(float(np.var(a[:n] - b[:n], ddof=1)), float(np.var(a[:n] - c[:n], ddof=1)), n, values)


def study_name(design: Path, spec: OptimizeSpec) -> str:
    """One study per design folder and table: a changed table starts a new study."""
    text = json.dumps([str(Path(design).resolve()), spec.model_dump(mode="json")], sort_keys=True)
    return "optimize-" + hashlib.sha256(text.encode()).hexdigest()[:16]


def optimize(options: OptimizeOptions, observer: OptimizeObserver | None = None) -> OptimizeResult:
    """Evaluate the start, measure the common-random-numbers effect, run (or resume) the study, then
    write the best as a revision and judge it against the start on fresh seeds (module docstring)."""
    import optuna  # lazy: keeps lensmount --help from loading optuna

    obs = observer or OptimizeObserver()
    spec = load_optimize(options.design, options.spec)
    trials = options.trials or spec.trials
    if trials < 1 or (options.budget is not None and options.budget < 0):
        raise InputError("trials must be at least 1 and the budget not negative", field="--trials",
                         valid="--trials N (N >= 1), --budget N (N >= 0)")
    s, out = Search(options, spec, obs), Path(options.out)
    rungs, reeval = spec.fidelity.passes, 2 * spec.fidelity.passes[-1]
    obs.stage("the start design")
    start = s.candidate(-1, start_values(s.design, spec.variables), out / "start")
    if not start.feasible:
        raise InputError(f"the start design cannot be optimised: {start.why}", file=str(s.design),
                         field="mount.toml", valid="a design that regenerates and meets the [optimize] constraints")
    for p in (*rungs, reeval):  # the first incumbent, evaluated as every incumbent is
        s.run(start, p)
    start.incumbent = True
    obs.stage("common random numbers: the start against a design 1 % away, shared and independent seeds")
    crn = crn_effect(s, start, out, reeval)
    search_seeds = (s.seed, s.seed + 1)  # the candidates' seed; the independent one of the measurement

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = s.store.parent / "optimize.sqlite"
    storage.parent.mkdir(parents=True, exist_ok=True)
    study = optuna.create_study(study_name=study_name(s.design, spec), storage=f"sqlite:///{storage}",
                                direction="minimize", load_if_exists=True)
    for stale in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        study.tell(stale.number, state=optuna.trial.TrialState.FAIL)  # stopped mid-candidate: asked again below
    done = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    candidates = [Candidate.from_dict(t.user_attrs["candidate"]) for t in sorted(done, key=lambda t: t.number)]
    incumbent = next((c for c in reversed(candidates) if c.incumbent), start)
    distributions = {key: _distribution(var) for key, var in spec.variables.items()}
    evaluated = 0
    while len(candidates) < trials and (options.budget is None or evaluated < options.budget):
        k = len(candidates)
        study.sampler = _sampler(spec.search.sampler_seed, k, trials)
        trial = study.ask(distributions)
        values = {key: _plain(trial.params[key], spec.variables[key]) for key in spec.variables}
        obs.stage(f"candidate {k + 1} of {trials}: " + ", ".join(f"{n} = {v}" for n, v in values.items()))
        c = s.candidate(k, values, out / "candidates" / f"{k:03d}")
        if c.feasible:
            try:
                incumbent = climb(s, c, incumbent, rungs, reeval)
            except InputError as error:  # the scene cannot be built on this mount
                c.feasible, c.why, c.runs = False, error.paragraph(), {}
        trial.set_user_attr("candidate", c.to_dict())
        trial.set_constraint("builds, passes its checks and meets the constraints", 0.0 if c.feasible else 1.0)
        study.tell(trial, c.value if c.feasible else INFEASIBLE)
        candidates.append(c)
        evaluated += 1
        obs.candidate(len(candidates), trials)
    result = OptimizeResult(spec, start, incumbent, candidates, crn, search_seeds,
                            finished=len(candidates) >= trials)
    result.importances = importances(study)
    if result.finished:
        verdict(s, result, out)
    result.paths = write_report(result, out)
    return result


def climb(s: Search, c: Candidate, incumbent: Candidate, rungs: tuple[int, ...], reeval: int) -> Candidate:
    """Run `c` up the rungs while it stays a contender; the incumbent after it (itself if it won)."""
    for p in rungs:
        s.run(c, p)
        (v, e), (vi, ei) = c.runs[p], incumbent.runs[p]
        if v - vi > CONTENDER_Z * math.hypot(e, ei):
            return incumbent
    if c.runs[rungs[-1]][0] >= incumbent.runs[rungs[-1]][0]:
        return incumbent
    s.run(c, reeval)  # a lucky draw on the top rung is not enough: twice its passes, as the incumbent had
    if c.runs[reeval][0] < incumbent.runs[reeval][0]:
        c.incumbent = True
        return c
    return incumbent


def verdict(s: Search, result: OptimizeResult, out: Path) -> None:
    """The best written as a revision (mount.toml, STEP, a row in the store) and judged against the
    start on a seed the search never used, by `compare`."""
    seed = max(result.search_seeds) + 1
    assert seed not in result.search_seeds
    result.verdict_seed = seed
    if result.best is result.start:
        return  # nothing beat the start: no revision to write or judge
    s.obs.stage(f"the verdict: the best and the start on seed {seed}, which the search never used")
    best = s.candidate(result.best.index, result.best.values, out / "best")
    if not best.feasible:  # it built in the search: the same values build again
        raise InputError(f"the best candidate no longer builds: {best.why}", field="optimize")
    passes = s.spec.fidelity.final_passes
    new, result.run_id = s.run(best, passes, seed=seed, out=out / "best" / "verdict-run", record=True)
    old, _ = s.run(result.start, passes, seed=seed, out=out / "start" / "verdict-run")
    judged = compare(CompareOptions(old, new, tolerance=0.0, confidence=s.spec.search.confidence,
                                    out=out / "verdict"), s.obs)
    result.verdict, result.revision = judged.verdict, best.folder / "design"


def importances(study) -> dict[str, float]:
    """Optuna's parameter importances (fANOVA); empty while the completed trials cannot support one."""
    import optuna  # lazy: keeps lensmount --help from loading optuna

    values = {t.value for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))}
    if len(values) < 2:
        return {}
    # its forest is random: seeded, the same study gives the same figures
    evaluator = optuna.importance.FanovaImportanceEvaluator(seed=0)
    return {k: float(v) for k, v in optuna.importance.get_param_importances(study, evaluator=evaluator).items()}


def _distribution(var: Variable):
    import optuna  # lazy: keeps lensmount --help from loading optuna

    if var.finishes is not None:
        return optuna.distributions.CategoricalDistribution(list(var.finishes))
    if var.integer:
        return optuna.distributions.IntDistribution(int(var.low), int(var.high))
    return optuna.distributions.FloatDistribution(var.low, var.high)


def _plain(value, var: Variable):
    """The value as mount.toml holds it (floats rounded to a micrometre: a revision reads as one)."""
    if var.finishes is not None:
        return str(value)
    return int(value) if var.integer else round(float(value), 3)


def _sampler(seed: int, k: int, trials: int):
    """TPE seeded for candidate k alone: what it proposes depends on the seed, k and the finished
    candidates, not on how many calls the study took."""
    import optuna  # lazy: keeps lensmount --help from loading optuna

    # infeasible candidates carry a constraint (Trial.set_constraint), which TPE keeps out of its good group
    return optuna.samplers.TPESampler(seed=seed * 1_000_003 + k, n_startup_trials=max(2, trials // 4))


__all__ = ["OptimizeObserver", "OptimizeOptions", "Search", "extent", "crn_effect",
           "per_pass_fraction", "start_values", "study_name", "optimize", "climb"]
