"""Faults in a running driver and its local worker pool, on the planar scene of tests/run (cheap):
SIGINT / SIGTERM after a seeded number of merged passes and a seeded delay, and SIGKILL of one or
all of the pool's workers. The run exits 0, 130 or 143 with no traceback, and (after --resume)
gives the uninterrupted run's pass fluxes exactly.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fault_log import record
from injection import seeds

ROOT = Path(__file__).resolve().parents[2]
PLANAR = ROOT / "tests" / "run" / "planar_run.py"
PASSES = 8


def _start(ck: Path, *args: str, delay: float = 0.2) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(PLANAR), str(ck), str(PASSES), "2", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "PLANAR_PASS_DELAY": str(delay)})


def _finish(proc: subprocess.Popen, lines: list[str]) -> dict:
    for line in proc.stdout:
        lines.append(line)
    proc.wait(timeout=300)
    err = proc.stderr.read()
    assert "Traceback" not in err, err[-3000:]
    return json.loads(lines[-1])


def _children(pid: int) -> list[int]:
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat[stat.rindex(")") + 2:].split()[1]) == pid:
                kids.append(int(entry.name))
    return sorted(kids)


@pytest.fixture(scope="module")
def straight(tmp_path_factory) -> dict:
    ck = tmp_path_factory.mktemp("straight") / "ck.npz"
    proc = _start(ck, delay=0.0)
    result = _finish(proc, [])
    assert proc.returncode == 0 and result["n"] == PASSES
    return result


def _params(kind: str, n: int, fast: int):
    return [pytest.param(s, id=f"seed{s}", marks=() if i < fast else pytest.mark.slow)
            for i, s in enumerate(seeds(kind, n))]


@pytest.mark.parametrize("seed", _params("planar-signal", 8, 1))
def test_signal_at_a_seeded_moment_resumes_identically(seed, straight, tmp_path):
    rng = random.Random(seed)
    after, pause, signum = rng.randint(1, PASSES - 2), rng.uniform(0.0, 0.3), rng.choice([signal.SIGINT,
                                                                                          signal.SIGTERM])
    ck = tmp_path / "ck.npz"
    proc = _start(ck)
    lines = []
    for line in proc.stdout:
        lines.append(line)
        if line.startswith(f"merged {after}"):
            time.sleep(pause)
            proc.send_signal(signum)
            break
    record(f"planar run: {signal.Signals(signum).name} {pause:.2f} s after pass {after} (seed {seed})")
    stopped = _finish(proc, lines)
    assert proc.returncode in (0, 130 if signum == signal.SIGINT else 143)
    if proc.returncode:
        assert stopped["interrupted"] and stopped["n"] >= after
        resumed = _finish(_start(ck, "--resume", delay=0.0), [])
    else:  # the run ended before the signal came
        resumed = stopped
    assert resumed["flux"] == straight["flux"]


@pytest.mark.parametrize("seed", _params("pool-kill", 8, 1))
def test_killed_pool_workers_are_replaced_identically(seed, straight, tmp_path):
    rng = random.Random(seed)
    after, which = rng.randint(1, PASSES - 2), rng.choice(["one", "all"])
    proc = _start(tmp_path / "ck.npz")
    lines = []
    for line in proc.stdout:
        lines.append(line)
        if line.startswith(f"merged {after}"):
            workers = _children(proc.pid)
            for pid in workers if which == "all" else workers[:1]:
                os.kill(pid, signal.SIGKILL)
            break
    record(f"local pool: {which} worker(s) SIGKILLed after pass {after} (seed {seed})")
    result = _finish(proc, lines)
    assert proc.returncode == 0 and result["flux"] == straight["flux"]
