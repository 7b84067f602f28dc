"""Dask workers lost at any moment: a scheduler and workers as separate processes on 127.0.0.1,
killed (SIGKILL, as an out-of-memory killer or a preempted node does) while a run goes on.

Losing every worker loses at most the passes in flight: the scene is sent again when a worker
comes back and the run ends with the same numbers as an uninterrupted local run; with no
worker back within --worker-wait the run keeps its checkpoint and exits 75, and a retry with
--resume finishes it identically.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fault_log import record

ROOT = Path(__file__).resolve().parents[2]
PLANAR = ROOT / "tests" / "run" / "planar_run.py"
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT / "tests" / "integrators"),
                                                     str(ROOT / "tests" / "run"), os.environ.get("PYTHONPATH", "")])}
DASK = Path(sys.executable).with_name("dask")

pytestmark = pytest.mark.slow


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for_workers(address: str, n: int, timeout: float = 120) -> None:
    from distributed import Client

    with Client(address, timeout="30s") as client:
        client.wait_for_workers(n, timeout=timeout)


class Cluster:
    """`dask scheduler` and `dask worker --no-nanny` processes (no nanny: a killed worker stays dead)."""

    def __init__(self, tmp: Path):
        self.address = f"tcp://127.0.0.1:{_free_port()}"
        self.tmp = tmp
        self.procs: list[subprocess.Popen] = []
        self.scheduler = self._start([str(DASK), "scheduler", "--host", "127.0.0.1", "--port",
                                      self.address.rsplit(":", 1)[1], "--no-dashboard"], "scheduler")
        self.workers: list[subprocess.Popen] = []

    def _start(self, argv, name) -> subprocess.Popen:
        log = open(self.tmp / f"{name}-{len(self.procs)}.log", "w")
        proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=ENV, start_new_session=True)
        self.procs.append(proc)
        return proc

    def add_worker(self) -> subprocess.Popen:
        worker = self._start([str(DASK), "worker", self.address, "--nthreads", "1", "--no-nanny",
                              "--no-dashboard"], "worker")
        self.workers.append(worker)
        return worker

    def close(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                proc.kill()
            proc.wait()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    yield c
    c.close()


def _planar(tmp_path, *args, name):
    out = subprocess.run([sys.executable, str(PLANAR), str(tmp_path / name), *map(str, args)], capture_output=True,
                         text=True, timeout=600, env=ENV)
    assert "Traceback" not in out.stderr, out.stderr[-3000:]
    return out.returncode, json.loads(out.stdout.strip().splitlines()[-1]), out


def _driver(tmp_path, cluster, passes, *extra, name="dask.npz"):
    return subprocess.Popen([sys.executable, str(PLANAR), str(tmp_path / name), str(passes), "1", "--scheduler",
                             cluster.address, *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**ENV, "PLANAR_PASS_DELAY": "0.5"})


def test_both_workers_killed_then_a_new_one_finishes_identically(tmp_path, cluster):
    rc, local, _ = _planar(tmp_path, 10, 1, name="local.npz")
    assert rc == 0
    first, second = cluster.add_worker(), cluster.add_worker()
    _wait_for_workers(cluster.address, 2)
    driver = _driver(tmp_path, cluster, 10)
    lines = []
    for line in driver.stdout:
        lines.append(line)
        if line.startswith("merged 2") and first.poll() is None:
            first.send_signal(signal.SIGKILL)
            record("dask: first of two workers SIGKILLed after pass 2")
        elif line.startswith("merged 4") and second.poll() is None:
            second.send_signal(signal.SIGKILL)
            record("dask: second (last) worker SIGKILLed after pass 4")
            time.sleep(2)
            cluster.add_worker()
        if line.startswith("{"):
            break
    driver.wait(timeout=300)
    assert driver.returncode == 0, driver.stderr.read()[-3000:]
    result = json.loads(lines[-1])
    assert result["n"] == 10 and result["flux"] == local["flux"]
    assert any("waiting up to" in line for line in lines)  # the scene went with its last holder, and was sent again


def test_no_worker_back_exits_75_with_its_checkpoint_and_a_retry_resumes(tmp_path, cluster):
    rc, local, _ = _planar(tmp_path, 8, 1, name="local.npz")
    only = cluster.add_worker()
    _wait_for_workers(cluster.address, 1)
    driver = _driver(tmp_path, cluster, 8, "--worker-wait", "5")
    lines = []
    for line in driver.stdout:
        lines.append(line)
        if line.startswith("merged 3") and only.poll() is None:
            only.send_signal(signal.SIGKILL)
            record("dask: the only worker SIGKILLed after pass 3, none started again")
            killed = time.monotonic()
    driver.wait(timeout=120)
    assert driver.returncode == 75, driver.stderr.read()[-3000:]
    assert time.monotonic() - killed < 5 + 60  # the documented limit, plus the checkpoint and Dask's own timeouts
    gone = json.loads(lines[-1])
    assert gone["workers_gone"] and gone["n"] >= 3
    assert any("waiting up to 5 s" in line for line in lines)
    cluster.add_worker()
    _wait_for_workers(cluster.address, 1)
    rc, resumed, out = _planar(tmp_path, 8, 1, "--resume", "--scheduler", cluster.address, name="dask.npz")
    assert rc == 0, out.stderr[-3000:]
    assert resumed["flux"] == local["flux"]
