"""Running passes until a stopping rule holds: workers, pass-order merge, checkpoint, Ctrl-C.

Passes are independent (pass i uses only (seed, i) and the radius scale s_i), so
passes may run in any worker in any order; the runner adds them to the Accumulator
strictly in pass order, which makes the result bit-identical for any `workers`.

Workers are processes (`ProcessPoolExecutor`); each builds its `Tracer` once in the
initializer, because Embree scenes do not pickle while the Scene (plain numpy) does.

Stopping rules (any that is given; at least one pass always runs):
  photons ≥ N,   elapsed ≥ T seconds,   relative error of the total flux ≤ E
  (checked only after `min_passes`, since an error bar from 2 passes is itself noise),
  passes ≥ max_passes.
"""

from __future__ import annotations

import importlib
import os
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from lensmount.analysis.passes import Accumulator
from lensmount.integrators.estimate import PassEstimate
from lensmount.integrators.radius import DEFAULT_ALPHA, radius_scale

PASS_FUNCTIONS = {
    "bidirectional": "lensmount.integrators.bidirectional:bidirectional_pass",
    "forward": "lensmount.integrators.forward:forward_pass",
}
TRACER = "lensmount.trace.tracer:Tracer"


def _resolve(path: str):
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


@dataclass
class Stopping:
    """Any rule that is set stops the run; max_passes always applies."""

    photons: int | None = None
    time_s: float | None = None
    target_rel_error: float | None = None
    max_passes: int = 10_000
    min_passes: int = 8

    def done(self, acc: Accumulator, elapsed: float) -> bool:
        if acc.n >= self.max_passes:
            return True
        if acc.n < 1:
            return False
        if self.photons is not None and acc.photons >= self.photons:
            return True
        if self.time_s is not None and elapsed >= self.time_s:
            return True
        if self.target_rel_error is not None and acc.n >= self.min_passes:
            return acc.rel_error() <= self.target_rel_error
        return False


@dataclass
class PassJob:
    """What a worker needs to compute pass `index` (all picklable)."""

    method: str
    photons: int
    seed: int
    index: int
    alpha: float = DEFAULT_ALPHA
    options: dict | None = None


# --- worker side -------------------------------------------------------------------------

_WORKER: dict = {}


def _init_worker(scene, tracer_path: str = TRACER) -> None:
    """Build the tracer once per process. Workers ignore Ctrl-C: the driver stops them and
    keeps the passes already merged (a worker killed mid-pass would break the pool)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER["scene"] = scene
    _WORKER["tracer"] = _resolve(tracer_path)(scene)


def run_pass(scene, tracer, job: PassJob) -> PassEstimate:
    """One pass of the chosen method, in this process."""
    fn = _resolve(PASS_FUNCTIONS.get(job.method, job.method))
    opts = job.options or {}
    if job.method == "bidirectional":
        return fn(scene, tracer, job.photons, job.seed, job.index, radius_scale(job.index, job.alpha), **opts)
    return fn(scene, tracer, job.photons, job.seed, job.index, **opts)


def _worker_pass(job: PassJob) -> tuple[int, PassEstimate]:
    return job.index, run_pass(_WORKER["scene"], _WORKER["tracer"], job)


# --- driver side -------------------------------------------------------------------------

class Runner:
    """Runs passes into an Accumulator.

    Args:
        scene: the Scene (pickled to workers).
        make_job: pass index -> PassJob.
        accumulator: where passes go (a resumed one continues after its last pass).
        workers: processes; 1 runs in this process (tests, debugging).
        checkpoint: path for the Accumulator state, written every `checkpoint_every` passes
            and on stop; `checkpoint_meta` goes along (seed, input hash, method).
        progress: called after every merged pass with (accumulator, elapsed seconds).
        tracer_path: "module:Class" building the tracer from the scene.
    """

    def __init__(self, scene, make_job: Callable[[int], PassJob], accumulator: Accumulator, *, workers: int = 1,
                 checkpoint: str | os.PathLike | None = None, checkpoint_meta: dict | None = None,
                 checkpoint_every: int = 8, progress: Callable | None = None, tracer_path: str = TRACER):
        self.scene = scene
        self.make_job = make_job
        self.acc = accumulator
        self.workers = max(1, int(workers))
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.meta = checkpoint_meta or {}
        self.every = max(1, checkpoint_every)
        self.progress = progress
        self.tracer_path = tracer_path
        self.interrupted = False
        self.elapsed = 0.0

    def save_checkpoint(self) -> None:
        if self.checkpoint is not None:
            self.acc.save(self.checkpoint, **self.meta)

    def _merge(self, index: int, estimate: PassEstimate, start: float) -> None:
        self.acc.add(estimate, pass_index=index)
        self.elapsed = time.perf_counter() - start
        if self.checkpoint is not None and self.acc.n % self.every == 0:
            self.save_checkpoint()
        if self.progress:
            self.progress(self.acc, self.elapsed)

    def run(self, stopping: Stopping) -> Accumulator:
        """Run until `stopping` holds or Ctrl-C; the checkpoint is written either way."""
        start = time.perf_counter() - self.elapsed
        try:
            if self.workers == 1:
                self._run_here(stopping, start)
            else:
                self._run_pool(stopping, start)
        except KeyboardInterrupt:
            self.interrupted = True
        self.elapsed = time.perf_counter() - start
        self.save_checkpoint()
        return self.acc

    def _run_here(self, stopping: Stopping, start: float) -> None:
        tracer = _resolve(self.tracer_path)(self.scene)
        while not stopping.done(self.acc, time.perf_counter() - start):
            job = self.make_job(self.acc.last_pass + 1)
            self._merge(job.index, run_pass(self.scene, tracer, job), start)

    def _run_pool(self, stopping: Stopping, start: float) -> None:
        # Keep a window of passes in flight; merge finished ones strictly in pass order.
        next_index = self.acc.last_pass + 1
        finished: dict[int, PassEstimate] = {}
        in_flight = {}
        window = 2 * self.workers
        with ProcessPoolExecutor(self.workers, initializer=_init_worker,
                                 initargs=(self.scene, self.tracer_path)) as pool:
            try:
                while True:
                    stop = stopping.done(self.acc, time.perf_counter() - start)
                    if not stop:
                        while len(in_flight) + len(finished) < window:
                            fut = pool.submit(_worker_pass, self.make_job(next_index))
                            in_flight[fut] = next_index
                            next_index += 1
                    if not in_flight:
                        break
                    if stop:  # passes already started are wasted; drop them rather than wait
                        for fut in in_flight:
                            fut.cancel()
                        break
                    done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                    for fut in done:
                        index, estimate = fut.result()
                        del in_flight[fut]
                        finished[index] = estimate
                    while self.acc.last_pass + 1 in finished:
                        i = self.acc.last_pass + 1
                        self._merge(i, finished.pop(i), start)
                        if stopping.done(self.acc, time.perf_counter() - start):
                            break
            except KeyboardInterrupt:
                for fut in in_flight:
                    fut.cancel()
                pool.shutdown(wait=False, cancel_futures=True)
                raise


def default_workers() -> int:
    return max(1, os.cpu_count() or 1)


__all__ = ["Runner", "Stopping", "PassJob", "run_pass", "default_workers", "PASS_FUNCTIONS"]
