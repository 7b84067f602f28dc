"""Where passes run: this process, local worker processes, or a Dask cluster.

The runner hands an executor picklable `PassJob`s and takes back `(index, PassEstimate)`;
it merges them strictly in pass order, so the result does not depend on the executor,
the number of workers or the order in which passes finish. Every executor

* sends the Scene (plain numpy) to each worker once per run, never once per task, and
  builds the Tracer there once (Embree scenes do not pickle);
* survives a worker that dies mid-pass: the pass is run again elsewhere, and since a
  pass depends only on (seed, index) the result is identical;
* leaves no worker behind when the driver dies, however it dies: local workers (and the
  worker processes of a `LocalCluster` started here) get SIGKILL from the kernel when
  their parent goes (Linux `PR_SET_PDEATHSIG`), and ignore SIGINT/SIGTERM meant for the
  process group, so the driver alone decides to checkpoint and stop.

`executor_for(workers=, scheduler=, cluster=)` chooses: a scheduler address joins an
existing Dask cluster, `cluster="local:N"` starts a Dask `LocalCluster` of N processes,
otherwise N local processes (1 = this process, for tests and debugging).
"""

from __future__ import annotations

import ctypes
import importlib
import logging
import multiprocessing
import os
import signal
import sys
import traceback
from collections import deque
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait

from lensmount.errors import InputError, WorkersGone
from lensmount.trace import lens_kernel
from lensmount.trace.jit_cache import load_cached

SCHEDULER_ENV = "LENSMOUNT_SCHEDULER"
WORKER_WAIT_S = 300.0  # how long a Dask run with no worker left waits for one before it stops (exit 75)
WORKER_DEATHS = 3  # a pass that kills this many local workers is a fault of the pass, not of a worker
_PR_SET_PDEATHSIG = 1
# The modules whose compiled kernels a pass calls: loaded from numba's cache before local workers are forked
KERNEL_MODULES = ("lensmount.trace.kernels", "lensmount.trace.lens_kernel",
                  "lensmount.integrators.photon_mapping.neighbours", "lensmount.integrators.photon_mapping.radius",
                  "lensmount.integrators.photon_mapping.photon_gather")


def resolve(path: str):
    """'module:name' → the object."""
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


def die_with_parent() -> None:
    """Make the kernel SIGKILL this process when its parent dies; ignore group signals.

    Called first thing in every worker process. On systems without prctl the worker still
    ignores SIGINT/SIGTERM and exits when the driver closes the pool normally.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    _sigkill_when_parent_dies()


def _sigkill_when_parent_dies() -> None:
    if sys.platform.startswith("linux"):
        parent = os.getppid()
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        if os.getppid() != parent:  # the parent died before prctl took effect
            os._exit(1)


# --- worker side: one Scene and one Tracer per process -------------------------------------

_WORKER: dict = {}  # this process's (key, scene, tracer)


def _tracer_for(scene, tracer_path: str):
    """The process's tracer for `scene`, built on first use (a new scene replaces the old)."""
    key = (id(scene), tracer_path)
    if _WORKER.get("key") != key:
        _WORKER.clear()
        _WORKER.update(key=key, scene=scene, tracer=resolve(tracer_path)(scene))  # holds scene: id stays unique
    return _WORKER["tracer"]


def _dask_pass(run_pass_path: str, scene, tracer_path: str, job):
    lens_kernel.one_core_per_process()  # a Dask worker's threads and its neighbours share the cores
    return job.index, resolve(run_pass_path)(scene, _tracer_for(scene, tracer_path), job)


# --- executors -----------------------------------------------------------------------------

class Executor:
    """The interface the runner uses: `start`, `submit(job)`, `in_flight`, `next_done()`, `close()`.

    `next_done()` blocks until at least one pass is finished and returns the finished
    `(index, PassEstimate)` pairs (possibly none after a lost worker, whose passes it
    has already sent out again).
    """

    workers: int = 1
    description: str = ""

    def start(self, scene, tracer_path: str, run_pass_path: str) -> None:
        self.scene, self.tracer_path, self.run_pass_path = scene, tracer_path, run_pass_path
        self._jobs: dict = {}  # handle → job, the passes sent out and not yet returned

    @property
    def in_flight(self) -> int:
        return len(self._jobs)

    def run_here(self, job):
        return job.index, resolve(self.run_pass_path)(self.scene, _tracer_for(self.scene, self.tracer_path), job)

    def close(self) -> None:
        self._jobs = {}


class InProcess(Executor):
    """Passes one after another in this process (workers = 1)."""

    workers, description = 1, "this process"

    def submit(self, job) -> None:
        self._jobs[len(self._jobs)] = job

    def next_done(self) -> list:
        job = self._jobs.pop(next(iter(self._jobs)))
        self._jobs = dict(enumerate(self._jobs.values()))
        return [self.run_here(job)]


class LocalProcesses(Executor):
    """N worker processes on this machine, each with its own pipe; a killed worker's pass is sent
    out again.

    Why not `concurrent.futures.ProcessPoolExecutor`: its workers write their results into one
    shared pipe that a thread of the driver reads. A worker killed while writing (a run that
    stops kills the passes in flight) leaves half a message there, and the driver's shutdown then
    waits for the rest forever: a run hung after its last pass that way. Here a worker's death
    closes only its own pipe, and the driver reads end-of-file.
    """

    def __init__(self, workers: int):
        self.workers = max(1, int(workers))
        self.description = f"{self.workers} local processes"
        self._idle: list[_Worker] = []
        self._busy: dict[_Worker, object] = {}  # worker → the pass it runs
        # Every worker started and not yet stopped, whatever list it is in: a signal can land between
        # taking a worker off `_idle` and putting it in `_busy`, and `close` must still stop it (a live
        # worker ignores SIGTERM, so multiprocessing's exit handler would wait for it forever).
        self._started: list[_Worker] = []

    def start(self, scene, tracer_path: str, run_pass_path: str) -> None:
        super().start(scene, tracer_path, run_pass_path)
        self._queue: deque = deque()  # passes not yet handed to a worker
        self._deaths: dict[int, int] = {}  # pass index → workers it has killed
        for name in KERNEL_MODULES:  # once here, inherited by every fork, not once per worker and run
            load_cached(vars(importlib.import_module(name)))
        self._idle = [self._spawn() for _ in range(self.workers)]

    @property
    def in_flight(self) -> int:
        return len(self._queue) + len(self._busy)

    def submit(self, job) -> None:
        self._queue.append(job)
        self._dispatch()

    def next_done(self) -> list:
        finished = []
        for conn in wait([worker.conn for worker in self._busy]) if self._busy else []:
            worker = next(w for w in self._busy if w.conn is conn)
            job = self._busy.pop(worker)
            try:
                message = conn.recv()
            except (EOFError, OSError):  # it died, maybe halfway through its message: run the pass again
                self._replace(worker)
                self._deaths[job.index] = self._deaths.get(job.index, 0) + 1
                if self._deaths[job.index] >= WORKER_DEATHS:
                    raise RuntimeError(f"pass {job.index} killed its worker process {WORKER_DEATHS} times (last "
                                       f"exit code {worker.process.exitcode}): not a passing failure") from None
                self._queue.appendleft(job)
                continue
            except BaseException:  # a message that does not unpickle: the run ends, and not with this worker alive
                worker.stop()
                raise
            self._idle.append(worker)
            if isinstance(message, _Failure):
                message.error.add_note(f"in worker process {worker.process.pid}:\n{message.trace}")
                raise message.error
            finished.append(message)
        self._dispatch()
        return finished

    def _dispatch(self) -> None:
        while self._queue and self._idle:
            worker, job = self._idle.pop(), self._queue.popleft()
            try:
                worker.conn.send(job)
            except OSError:  # it died while idle
                self._queue.appendleft(job)
                self._replace(worker)
                continue
            self._busy[worker] = job

    def _spawn(self) -> "_Worker":
        context = multiprocessing.get_context("fork")  # the scene reaches the worker without pickling
        conn, child = context.Pipe()
        process = context.Process(target=_local_worker, daemon=True,
                                  args=(child, self.scene, self.tracer_path, self.run_pass_path))
        worker = _Worker(process, conn)
        self._started.append(worker)  # before it starts: `close` stops it even if a signal lands now
        process.start()
        child.close()  # the worker alone holds its end: its death is end-of-file here
        return worker

    def _replace(self, worker: "_Worker") -> None:
        worker.stop()
        self._started.remove(worker)
        self._idle.append(self._spawn())

    def close(self) -> None:
        # Passes in flight are not waited for: a stopped run redoes them on resume, identically.
        for worker in self._started:
            worker.stop()
        self._idle, self._busy, self._started = [], {}, []
        super().close()


@dataclass(eq=False)
class _Worker:
    process: multiprocessing.process.BaseProcess
    conn: Connection

    def stop(self) -> None:
        if self.process.pid is not None:  # started
            self.process.kill()
            self.process.join()
        self.conn.close()


@dataclass
class _Failure:
    """A pass that raised in a worker: the driver raises the same error (a pass that fails fails the run)."""

    error: BaseException
    trace: str


def _local_worker(conn: Connection, scene, tracer_path: str, run_pass_path: str) -> None:
    """A local worker's life: passes from its pipe, their results back, one tracer, until killed."""
    die_with_parent()
    lens_kernel.one_core_per_process()  # the workers share the cores already
    run_pass = resolve(run_pass_path)
    while True:
        job = conn.recv()
        try:
            message = (job.index, run_pass(scene, _tracer_for(scene, tracer_path), job))
        except Exception as error:
            message = _Failure(error, traceback.format_exc())
        try:
            conn.send(message)
        except Exception as error:  # it does not pickle (nothing was written): say why, not die as if crashed
            conn.send(_Failure(RuntimeError(f"pass {job.index}'s result cannot be sent back: {error}"),
                               traceback.format_exc()))


class DaskCluster(Executor):
    """Passes as Dask tasks on an existing cluster (`address`) or a LocalCluster of `local_workers` processes.

    The Scene is scattered to every worker (`broadcast=True`); each task names it by its
    future, so only the small PassJob travels per task, and a worker that joins later fetches
    it from one that holds it. Dask re-runs the tasks of a worker that dies; passes are pure
    functions of (seed, index), so nothing changes. When every holder of the scene is gone (the
    last worker died), Dask forgets the scene and cancels the passes that need it: the scene is
    sent again to the workers there are, waiting up to `wait_s` for one to appear (told through
    `say`), and the passes in flight are submitted again. No worker within `wait_s`:
    `WorkersGone` (the runner keeps what is merged; the command exits 75).
    """

    def __init__(self, address: str | None = None, local_workers: int | None = None,
                 wait_s: float = WORKER_WAIT_S, say=None):
        self.address, self.local_workers = address, local_workers
        self.workers = local_workers or 1
        self.description = f"Dask ({address or f'LocalCluster of {local_workers} processes'})"
        self.wait_s, self.say = wait_s, say or (lambda text: None)
        self._client = self._cluster = None

    def start(self, scene, tracer_path: str, run_pass_path: str) -> None:
        super().start(scene, tracer_path, run_pass_path)
        from distributed import Client, LocalCluster  # lazy: keeps lensmount --help from loading dask

        if self.address:
            self._client = Client(self.address, timeout="20s")
        else:
            self._cluster = LocalCluster(n_workers=self.local_workers, threads_per_worker=1, processes=True,
                                         dashboard_address=None, silence_logs=logging.ERROR)
            self._client = Client(self._cluster)
            self._client.register_plugin(_die_with_parent_plugin())
        self._send_scene()
        self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))

    def _send_scene(self) -> None:
        """The scene to every worker there is, after waiting up to `wait_s` for one."""
        if not self._client.scheduler_info().get("workers"):
            self.say(f"no Dask worker at {self.address or 'the local cluster'}: waiting up to {self.wait_s:g} s "
                     "for one (start workers: docs/scale.md)")
            try:
                self._client.wait_for_workers(1, timeout=self.wait_s)
            except TimeoutError:
                raise WorkersGone(f"no Dask worker at {self.address or 'the local cluster'} for {self.wait_s:g} s"
                                  ) from None
            self.say("a Dask worker is back: the passes in flight are sent again")
        self._scene = self._client.scatter(self.scene, broadcast=True, hash=False)

    def submit(self, job) -> None:
        future = self._client.submit(_dask_pass, self.run_pass_path, self._scene, self.tracer_path, job,
                                     pure=False, retries=3)
        self._jobs[future] = job

    def next_done(self) -> list:
        from distributed import wait as dask_wait  # lazy: keeps lensmount --help from loading dask
        from distributed.client import FuturesCancelledError

        try:
            done = dask_wait(list(self._jobs), return_when="FIRST_COMPLETED").done
        except FuturesCancelledError:  # the scene went with its last holder: the passes that need it are cancelled
            done = None
        if done is None or any(future.status in ("cancelled", "lost") for future in done):
            jobs = list(self._jobs.values())
            for future in self._jobs:
                future.cancel()
            self._jobs = {}
            self._send_scene()
            for job in jobs:
                self.submit(job)
            return []
        finished = [future.result() for future in done]
        for future in done:
            del self._jobs[future]
        return finished

    def close(self) -> None:
        for future in self._jobs:
            future.cancel()
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None
        super().close()


def _die_with_parent_plugin():
    """A Dask worker plugin: LocalCluster workers are our children; they must not outlive us."""
    from distributed import WorkerPlugin  # lazy: keeps lensmount --help from loading dask

    class DieWithParent(WorkerPlugin):
        name = "lensmount-die-with-parent"

        def setup(self, worker) -> None:
            _sigkill_when_parent_dies()

    return DieWithParent()


def local_cluster_size(cluster: str) -> int:
    """N of 'local:N'; InputError for anything else (checked before a run builds anything)."""
    kind, _, n = cluster.partition(":")
    if kind != "local" or not n.isdigit() or int(n) < 1:
        raise InputError(f"cluster '{cluster}' is not understood", field="--cluster",
                         valid="local:N with N ≥ 1, e.g. local:4")
    return int(n)


def executor_for(workers: int = 1, scheduler: str | None = None, cluster: str | None = None,
                 worker_wait_s: float = WORKER_WAIT_S, say=None) -> Executor:
    """The executor the options ask for (see the module docstring); a Dask one waits up to
    `worker_wait_s` for a worker when it has none, telling `say(text)`."""
    scheduler = scheduler or os.environ.get(SCHEDULER_ENV) or None
    if scheduler and cluster:
        raise InputError("give either a scheduler address or a local cluster, not both", field="--cluster",
                         valid=f"--scheduler ADDRESS (or {SCHEDULER_ENV}) | --cluster local:N")
    if scheduler:
        return DaskCluster(address=scheduler, wait_s=worker_wait_s, say=say)
    if cluster:
        return DaskCluster(local_workers=local_cluster_size(cluster), wait_s=worker_wait_s, say=say)
    if workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}", field="--workers",
                         valid="an integer ≥ 1 (0 in the CLI means one per core)")
    return InProcess() if workers == 1 else LocalProcesses(workers)


__all__ = ["Executor", "InProcess", "LocalProcesses", "DaskCluster", "executor_for", "local_cluster_size",
           "die_with_parent",
           "resolve", "SCHEDULER_ENV", "WORKER_WAIT_S"]
