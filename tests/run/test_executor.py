"""Executors: the same seed gives the same numbers on any executor; signals and dead workers.

The planar scene of tests/integrators runs in a subprocess (`planar_run.py`), so that the
tests can kill it, and its workers, the way a batch system does.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
SCRIPT = HERE / "planar_run.py"


def _run(tmp_path, *args, name="ck.npz", env=None):
    out = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path / name), *map(str, args)],
                         capture_output=True, text=True, timeout=300, env={**os.environ, **(env or {})})
    assert out.returncode in (0, 130, 143), out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1]), out


def _session_members(sid: int) -> list[int]:
    """Live processes of session `sid` (a run started with start_new_session, and every child it made)."""
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if fields[0] != "Z" and int(fields[3]) == sid:  # state, ppid, pgrp, session
            members.append(int(entry.name))
    return members


def test_one_and_two_local_workers_agree(tmp_path):
    one, _ = _run(tmp_path, 6, 1, name="a.npz")
    two, _ = _run(tmp_path, 6, 2, name="b.npz")
    assert one["n"] == two["n"] == 6
    assert one["flux"] == two["flux"]


def test_dead_local_worker_is_replaced_with_identical_result(tmp_path):
    straight, _ = _run(tmp_path, 6, 2, name="a.npz")
    crashed, _ = _run(tmp_path, 6, 2, "--crash-once", tmp_path / "marker", name="b.npz")
    assert (tmp_path / "marker").exists()  # a worker really died
    assert crashed["flux"] == straight["flux"]


@pytest.mark.slow
@pytest.mark.parametrize("cluster", ["local:2", "local:1"], ids=["one-of-two", "the-last"])
def test_dead_dask_worker_is_replaced_with_identical_result(tmp_path, cluster):
    """A Dask worker dies in pass 3 (`crashing_pass`, a module the workers import); its nanny starts
    another. With one worker the scene's only holder went with it: the run says so and sends the scene
    again. Either way the numbers are those of this process's run (so Dask agrees with it: the passes
    other than 3 ran on Dask undisturbed), and nothing is said in tracebacks."""
    straight, _ = _run(tmp_path, 6, 1, name="a.npz")
    crashed, out = _run(tmp_path, 6, 1, "--cluster", cluster, "--crash-once", tmp_path / "marker", name="b.npz")
    assert (tmp_path / "marker").exists()  # a worker really died
    assert crashed["n"] == 6 and crashed["flux"] == straight["flux"]
    assert "Traceback" not in out.stderr, out.stderr[-3000:]
    if cluster == "local:1":
        assert "a Dask worker is back: the passes in flight are sent again" in out.stdout, out.stdout


@pytest.mark.parametrize("how", [pytest.param(signal.SIGKILL, marks=pytest.mark.slow), signal.SIGTERM,
                                 pytest.param(signal.SIGINT, marks=pytest.mark.slow)])
def test_killed_run_resumes_identically_and_leaves_no_process(tmp_path, how):
    ck = tmp_path / "ck.npz"
    proc = subprocess.Popen([sys.executable, str(SCRIPT), str(ck), "40", "2"], stdout=subprocess.PIPE, text=True,
                            start_new_session=True, env={**os.environ, "PLANAR_PASS_DELAY": "0.2"})
    for line in proc.stdout:  # wait until a few passes are merged (and checkpointed)
        if line.startswith("merged 3"):
            break
    proc.send_signal(how)
    proc.wait(timeout=60)
    if how != signal.SIGKILL:
        assert proc.returncode == (143 if how == signal.SIGTERM else 130)
    deadline = time.time() + 10
    while _session_members(proc.pid) and time.time() < deadline:
        time.sleep(0.1)
    assert _session_members(proc.pid) == [], "a worker outlived its parent"
    resumed, _ = _run(tmp_path, 10, 2, "--resume")
    straight, _ = _run(tmp_path, 10, 2, name="straight.npz")
    assert resumed["flux"] == straight["flux"]
    # The time before the kill is counted too: "merged 3" is printed after two 0.2 s pauses.
    assert resumed["elapsed_s"] > 0.4


def test_bad_cluster_is_refused_before_anything_is_built(tmp_path):
    from lensmount.errors import InputError
    from lensmount.loop.simulate import SimulateOptions, check_options

    for bad in ("local", "local:0", "remote:3", "local:x"):
        with pytest.raises(InputError) as e:
            check_options(SimulateOptions(tmp_path, tmp_path / "s.toml", cluster=bad))
        assert e.value.field == "--cluster"
    with pytest.raises(InputError):
        check_options(SimulateOptions(tmp_path, tmp_path / "s.toml", cluster="local:2", scheduler="tcp://h:8786"))


_BIG_RESULT = """
import sys, time
from pathlib import Path
from types import SimpleNamespace
import numpy as np
from lensmount.run.executor import LocalProcesses

MARKER, DELAY = Path(sys.argv[1]), float(sys.argv[2])

class Announced:
    \"\"\"320 MB whose pickling (just before the worker sends it) leaves the marker.\"\"\"
    def __init__(self, data):
        self.data = data
    def __reduce__(self):
        MARKER.write_text("sending")
        return (Announced, (self.data,))

def no_tracer(scene):
    return None

def big_pass(scene, tracer, job):
    return Announced(np.ones(40_000_000))

if __name__ == "__main__":
    workers = LocalProcesses(2)
    workers.start(None, "__main__:no_tracer", "__main__:big_pass")
    workers.submit(SimpleNamespace(index=0))
    while not MARKER.exists():
        time.sleep(0.001)
    time.sleep(DELAY)
    workers.close()
    print("closed")
"""


@pytest.mark.parametrize("delay_s", [0.2, 0.4, 0.6])
def test_a_run_stopped_while_a_worker_sends_its_result_ends(tmp_path, delay_s):
    """The driver stops (the pass limit reached, Ctrl-C) while a worker is pickling or halfway
    through sending a pass's result: closing kills the worker and returns. With the results of all
    workers in one shared pipe read by a driver thread (concurrent.futures' ProcessPoolExecutor,
    used before), the close 0.4 s after the pickling began waited for the rest of the message
    forever: a simulate run hung after its last pass that way."""
    script = tmp_path / "big_result.py"
    script.write_text(_BIG_RESULT)
    out = subprocess.run([sys.executable, str(script), str(tmp_path / "marker"), str(delay_s)], capture_output=True,
                         text=True, timeout=60, cwd=HERE.parents[1])
    assert out.returncode == 0 and out.stdout.strip() == "closed", out.stderr[-2000:]


_UNSENDABLE = """
import sys, threading
from types import SimpleNamespace
from lensmount.run.executor import LocalProcesses

def no_tracer(scene):
    return None

def unsendable_pass(scene, tracer, job):
    return job.index, threading.Lock()  # does not pickle

if __name__ == "__main__":
    workers = LocalProcesses(1)
    workers.start(None, "__main__:no_tracer", "__main__:unsendable_pass")
    workers.submit(SimpleNamespace(index=0))
    try:
        workers.next_done()
    except RuntimeError as error:
        print("raised:", error)
    finally:
        workers.close()
"""


def test_a_result_that_cannot_be_sent_fails_the_run_with_the_reason(tmp_path):
    """A pass whose result does not pickle fails the run saying so, once (not three worker deaths)."""
    script = tmp_path / "unsendable.py"
    script.write_text(_UNSENDABLE)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60, cwd=HERE.parents[1])
    assert out.returncode == 0, out.stderr[-2000:]
    assert "raised: pass 0's result cannot be sent back" in out.stdout and "lock" in out.stdout
