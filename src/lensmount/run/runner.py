"""Running passes until a stopping rule holds: workers, pass-order merge, checkpoint, Ctrl-C.

Passes are independent (pass i uses only (seed, i) and the radius scale s_i), so
passes may run in any worker in any order; the runner adds them to the Accumulator
strictly in pass order, which makes the result bit-identical for any `workers`.

Where passes run is the executor's business (`lensmount.run.executor`: this process, local
processes, or a Dask cluster); each worker builds its `Tracer` once, because Embree scenes
do not pickle while the Scene (plain numpy) does. SIGINT and SIGTERM stop a run the same
way: the passes merged so far are kept and the checkpoint is written.

Stopping rules (any that is given; at least one pass always runs):
  photons ≥ N,   elapsed ≥ T seconds,
  (standard error + kernel-bias bound) / total flux ≤ E (`Accumulator.rel_error`; checked
  only after `min_passes`, since an error bar from 2 passes is itself noise; never met by a
  run with no signal, whose relative error is unknown, nor while one pass dominates the
  others, `Accumulator.converged`: its error bar is the spread of a heavy tail),
  passes ≥ max_passes.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from lensmount.analysis.passes import Accumulator
from lensmount.errors import WorkersGone
from lensmount.run.executor import Executor, executor_for
from lensmount.run.signals import Terminated, deferred, stop_on_signals
from lensmount.integrators.estimate import PassEstimate
from lensmount.integrators.registry import integrator
from lensmount.integrators.settings import EstimatorSettings

TRACER = "lensmount.trace.tracer:Tracer"
RUN_PASS = "lensmount.run.runner:run_pass"


@dataclass
class Stopping:
    """Any rule that is set stops the run; max_passes always applies."""

    photons: int | None = None
    time_s: float | None = None
    target_rel_error: float | None = None
    max_passes: int = 10_000
    min_passes: int = 8
    time_after_passes: int = 1  # the time rule stops no run before this many passes (a cap: 3, an error bar)

    def done(self, acc: Accumulator, elapsed: float) -> bool:
        if acc.n >= self.max_passes:
            return True
        if acc.n < 1:
            return False
        if self.photons is not None and acc.photons >= self.photons:
            return True
        if self.time_s is not None and elapsed >= self.time_s and acc.n >= self.time_after_passes:
            return True
        if self.target_rel_error is not None and acc.n >= self.min_passes:
            return acc.converged(self.target_rel_error)
        return False


@dataclass
class PassJob:
    """What a worker needs to compute pass `index` (all picklable): method, photons per pass
    (every pass of a run has the same count: photon k of pass i is photon i·photons + k), seed."""

    method: str
    photons: int
    seed: int
    index: int
    settings: EstimatorSettings = EstimatorSettings()


def run_pass(scene, tracer, job: PassJob) -> PassEstimate:
    """One pass of the chosen method, in this process."""
    return integrator(job.method, job.settings).run_pass(scene, tracer, job.index, job.photons, job.seed)


# --- driver side -------------------------------------------------------------------------

class Runner:
    """Runs passes into an Accumulator.

    Args:
        scene: the Scene (sent to each worker once).
        make_job: pass index -> PassJob (or what `run_pass_path` takes).
        accumulator: where passes go (a resumed one continues after its last pass, and its
            `elapsed_s` keeps counting, so the run's time is the total over resumed parts). An
            Accumulator, or anything with its `add(result, pass_index)`, `n`, `last_pass`, `elapsed_s`
            that `stopping.done` reads (`loop.pst`'s tally of every angle's Accumulator).
        workers: local processes; 1 runs in this process (tests, debugging). Ignored when
            `executor` is given.
        executor: where passes run (`lensmount.run.executor.executor_for`); default from `workers`.
        checkpoint: path for the Accumulator state, written every `checkpoint_every` passes
            and on stop; `checkpoint_meta` goes along (seed, input hash, method).
        progress: called after every merged pass with (accumulator, elapsed seconds).
        tracer_path: "module:Class" building the tracer from the scene.
        run_pass_path: "module:function" computing a job in a worker, (scene, tracer, job) -> result.
        window: passes in flight at once (default: two per worker, so none waits for a merge; a sweep
            whose jobs carry only the angles still running takes one per worker: fewer passes past a stop).
    """

    def __init__(self, scene, make_job: Callable[[int], PassJob], accumulator: Accumulator, *, workers: int = 1,
                 executor: Executor | None = None, checkpoint: str | os.PathLike | None = None,
                 checkpoint_meta: dict | None = None, checkpoint_every: int = 8, progress: Callable | None = None,
                 tracer_path: str = TRACER, run_pass_path: str = RUN_PASS, window: int | None = None):
        self.scene = scene
        self.make_job = make_job
        self.acc = accumulator
        self.executor = executor or executor_for(workers=max(1, int(workers)))
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.meta = checkpoint_meta or {}
        self.every = max(1, checkpoint_every)
        self.progress = progress
        self.tracer_path = tracer_path
        self.run_pass_path = run_pass_path
        self.window = window
        self.interrupted = False
        self.terminated = False  # stopped by SIGTERM rather than Ctrl-C
        self.workers_gone: str | None = None  # stopped because no Dask worker came back: why

    @property
    def elapsed(self) -> float:
        return self.acc.elapsed_s

    def save_checkpoint(self) -> None:
        """The accumulator to the checkpoint, when it holds a pass (a stop before the first one leaves no file)."""
        if self.checkpoint is not None and self.acc.n:
            self.acc.save(self.checkpoint, **self.meta)

    def _merge(self, index: int, estimate: PassEstimate, start: float, base: float) -> None:
        with deferred():  # a signal here waits: half a pass in the sums would resume to other numbers
            self.acc.add(estimate, pass_index=index)
            self.acc.elapsed_s = base + time.perf_counter() - start
            if self.checkpoint is not None and self.acc.n % self.every == 0:
                self.save_checkpoint()
            if self.progress:
                self.progress(self.acc, self.acc.elapsed_s)

    def run(self, stopping: Stopping) -> Accumulator:
        """Run until `stopping` holds, Ctrl-C, SIGTERM or the loss of every Dask worker for longer than
        the executor waits; the checkpoint is written either way (when a pass is complete: a stop
        before the first leaves none)."""
        start, base = time.perf_counter(), self.acc.elapsed_s
        with stop_on_signals():
            try:
                try:
                    self.executor.start(self.scene, self.tracer_path, self.run_pass_path)
                    self._run(stopping, start, base)
                finally:
                    self.executor.close()
            except KeyboardInterrupt as stop:
                self._stopped(stop)
            except WorkersGone as gone:  # the merged passes are kept as for a signal; a retry resumes
                self.interrupted, self.workers_gone = True, str(gone)
            try:
                with deferred():
                    self.acc.elapsed_s = base + time.perf_counter() - start
                    self.save_checkpoint()
            except KeyboardInterrupt as stop:  # arrived while the checkpoint was written: it is whole
                self._stopped(stop)
        return self.acc

    def _stopped(self, stop: KeyboardInterrupt) -> None:
        if not self.interrupted:
            self.interrupted = True
            self.terminated = isinstance(stop, Terminated)

    def _run(self, stopping: Stopping, start: float, base: float) -> None:
        # Keep a window of passes in flight; merge finished ones strictly in pass order.
        next_index = self.acc.last_pass + 1
        finished: dict[int, PassEstimate] = {}
        window = self.window or (2 * self.executor.workers if self.executor.workers > 1 else 1)
        last = next_index + max(stopping.max_passes - self.acc.n, 0)  # no pass past the limit is started
        while not stopping.done(self.acc, base + time.perf_counter() - start):
            while self.executor.in_flight + len(finished) < window and next_index < last:
                self.executor.submit(self.make_job(next_index))
                next_index += 1
            for index, estimate in self.executor.next_done():
                finished[index] = estimate
            while self.acc.last_pass + 1 in finished:
                self._merge(self.acc.last_pass + 1, finished.pop(self.acc.last_pass + 1), start, base)
                if stopping.done(self.acc, base + time.perf_counter() - start):
                    return  # passes still in flight are dropped: merging them would depend on timing


def default_workers() -> int:
    return max(1, os.cpu_count() or 1)


__all__ = ["Runner", "Stopping", "PassJob", "run_pass", "default_workers"]
