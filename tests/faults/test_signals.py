"""SIGINT and SIGTERM at seeded moments of every phase of `simulate` and `regenerate`.

The command runs in this process (typer's CliRunner, Python's own signal handling) with one
of its phases wrapped so that its k-th call sends the signal to this process: reading the
inputs, the geometry, the scene, the plan, starting the executor, the pilot, the view map, the
photons, the gather, the merge, the checkpoint, the results, paths.npz, the store. The phase,
k and the signal come from the case's seed (recorded). Each case must end in exit 0, 130 or
143, with one line and no traceback, nothing half-written, and the state must resume (or,
when nothing was kept, rerun) to the numbers of the uninterrupted run, bit for bit.
"""

from __future__ import annotations

import os
import random
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fault_log import record
from injection import seeds

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "src" / "lensmount" / "examples" / "cooke-triplet"
TINY_SCENE = (EXAMPLE / "scenes" / "case1-diaphragm-edge.toml").read_text().replace("pixels = [360, 240]",
                                                                                    "pixels = [36, 24]")
RUN = ["--passes", "3", "--photons-per-pass", "2000", "--workers", "1"]


def _phases():
    """phase → (object, attribute, how many calls a run makes at least): where a signal is sent."""
    from lensmount.analysis.passes import Accumulator
    from lensmount.cad import pipeline
    from lensmount.integrators import bidirectional
    from lensmount.integrators.photon_mapping.photon_gather import Gatherer
    from lensmount.loop import prepare, simulate
    from lensmount.run.executor import InProcess
    from lensmount.run.store import Store
    from lensmount.scene import build

    # a function is hooked where the caller looks it up: the module that imported it at its top
    return {"read the design": (prepare, "load_design", 1), "geometry": (pipeline, "regenerate", 1),
            "scene": (build, "build_scene", 1), "plan": (simulate, "plan", 1), "executor": (InProcess, "start", 1),
            "pilot": (bidirectional, "edge_band", 3), "view map": (bidirectional, "build_view_map", 3),
            "photons": (bidirectional, "photon_walk", 3), "gather": (Gatherer, "gather", 3),
            "merge": (Accumulator, "add", 3), "checkpoint": (Accumulator, "save", 1),
            "results": (simulate, "write_run", 1), "paths.npz": (simulate, "write_paths", 1),
            "store": (Store, "record", 1)}


def arm(monkeypatch, owner, name: str, k: int, signum: int, fired: list) -> None:
    """owner.name sends `signum` to this process on its k-th call (then runs as usual)."""
    original = getattr(owner, name)
    calls = [0]

    def hooked(*args, **kwargs):
        calls[0] += 1
        if calls[0] == k:
            fired.append(k)
            os.kill(os.getpid(), signum)
        return original(*args, **kwargs)

    monkeypatch.setattr(owner, name, hooked)


@pytest.fixture(autouse=True)
def harmless_late_signal():
    """A signal that arrived after the command returned must not end pytest (SIGTERM's default)."""
    previous = signal.signal(signal.SIGTERM, lambda *a: None)
    yield
    signal.signal(signal.SIGTERM, previous)


@pytest.fixture(scope="module")
def design(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("signals") / "cooke-triplet"
    shutil.copytree(EXAMPLE, folder)
    (folder / "scenes" / "tiny.toml").write_text(TINY_SCENE)
    return folder


@pytest.fixture(scope="module")
def reference(design, tmp_path_factory):
    """The uninterrupted run (and the geometry, built once for the module)."""
    from lensmount.analysis.passes import Accumulator
    from lensmount.cli import app

    out = tmp_path_factory.mktemp("reference") / "out"
    result = CliRunner().invoke(app, _simulate(design, out, tmp_path_factory.mktemp("store") / "runs.sqlite"))
    assert result.exit_code == 0, result.output
    reference = Accumulator.load(out / "checkpoint.npz")[0]
    reference.out = out  # the results folder, for compare
    return reference


def _simulate(design: Path, out: Path, store: Path, *extra: str) -> list[str]:
    return ["simulate", str(design), "--scene", str(design / "scenes" / "tiny.toml"), "--out", str(out),
            "--store", str(store), *RUN, *extra]


def _no_half_files(*folders: Path) -> None:
    for folder in folders:
        if folder.exists():
            leftovers = [p for p in folder.rglob("*") if p.name.endswith(".tmp") or ".tmp." in p.name]
            assert leftovers == [], leftovers


PHASES = ("read the design", "geometry", "scene", "plan", "executor", "pilot", "view map", "photons", "gather",
          "merge", "checkpoint", "results", "paths.npz", "store")


def _cases():
    """One seed per phase (the full suite's budget); each seed picks the call and the signal."""
    cases = []
    for i, seed in enumerate(seeds("simulate-signal", len(PHASES))):
        phase, signum = PHASES[i % len(PHASES)], random.Random(seed).choice([signal.SIGINT, signal.SIGTERM])
        cases.append(pytest.param(phase, seed, signum, id=f"{phase}-{signal.Signals(signum).name}-seed{seed}"))
    return cases


@pytest.mark.slow
@pytest.mark.parametrize("phase, seed, signum", _cases())
def test_signal_in_simulate(phase, seed, signum, design, reference, tmp_path, monkeypatch):
    from lensmount.analysis.passes import Accumulator
    from lensmount.cli import app
    from lensmount.run.results import read_summary

    owner, name, calls = _phases()[phase]
    k = random.Random(seed + 1).randint(1, calls)
    fired: list = []
    arm(monkeypatch, owner, name, k, signum, fired)
    out, store = tmp_path / "out", tmp_path / "runs.sqlite"
    result = CliRunner().invoke(app, _simulate(design, out, store))
    monkeypatch.undo()
    assert fired, f"{phase}: call {k} never came"
    record(f"simulate: {signal.Signals(signum).name} at call {k} of {phase} (seed {seed})")
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output
    code = 143 if signum == signal.SIGTERM else 130
    assert result.exit_code == code, result.output
    last = result.output.strip().splitlines()[-1]
    assert last.startswith(signal.Signals(signum).name), last  # one line that says what happened and what next
    _no_half_files(out, design / "build")
    checkpoint = out / "checkpoint.npz"
    if checkpoint.exists():  # the passes kept, and results that agree with them
        kept = Accumulator.load(checkpoint)[0]
        assert read_summary(out / "summary.json")["passes"] == kept.n > 0
        assert "--resume" in last or "complete" in last
        again = CliRunner().invoke(app, _simulate(design, out, store, "--resume"))
    else:
        assert not out.exists() or not any(out.iterdir()), "nothing kept, so nothing written"
        assert "run the same command again" in last
        again = CliRunner().invoke(app, _simulate(design, out, store, "--resume"))  # what a batch retry does
    assert again.exit_code == 0, again.output
    final = Accumulator.load(checkpoint)[0]
    assert final.pass_flux == reference.pass_flux and np.array_equal(final.sum_image, reference.sum_image)
    assert np.array_equal(final.sum_parts, reference.sum_parts)


@pytest.mark.slow
def test_nothing_kept_means_nothing_written(design, reference, tmp_path, monkeypatch):
    """A signal before the first pass: no results folder, no 0-pass checkpoint (the reported bug
    left one, after a ValueError from analysis/paths.py)."""
    from lensmount.cli import app
    from lensmount.run.executor import InProcess

    fired: list = []
    arm(monkeypatch, InProcess, "next_done", 1, signal.SIGTERM, fired)  # while the first pass is traced
    out = tmp_path / "out"
    result = CliRunner().invoke(app, _simulate(design, out, tmp_path / "runs.sqlite"))
    record("simulate: SIGTERM while the first pass is traced")
    assert fired and result.exit_code == 143, result.output
    assert "ValueError" not in result.output and not out.exists()
    assert "before the first pass was complete" in result.output


@pytest.mark.slow
@pytest.mark.parametrize("seed", seeds("regenerate-signal", 3))
def test_signal_in_regenerate(seed, design, reference, tmp_path, monkeypatch):
    """A stopped regenerate leaves the build folder as it was (here: none), never empty or half."""
    from lensmount.cad import pipeline
    from lensmount.cli import app
    from lensmount.mesh import TaggedMesh

    rng = random.Random(seed)
    owner, name, calls = rng.choice([(pipeline, "build_assembly", 1), (pipeline, "tessellate", 1),
                                     (pipeline, "write_part_step", 8), (pipeline, "write_assembly_step", 1)])
    k = rng.randint(1, calls)
    signum = rng.choice([signal.SIGINT, signal.SIGTERM])
    copy = tmp_path / "design"
    shutil.copytree(design, copy, ignore=shutil.ignore_patterns("build", ".lensmount"))
    fired: list = []
    arm(monkeypatch, owner, name, k, signum, fired)
    result = CliRunner().invoke(app, ["regenerate", str(copy), "-q"])
    monkeypatch.undo()
    record(f"regenerate: {signal.Signals(signum).name} at call {k} of {name} (seed {seed})")
    assert fired and result.exit_code == (143 if signum == signal.SIGTERM else 130), result.output
    assert "Traceback" not in result.output
    assert not (copy / "build").exists() and [p.name for p in copy.iterdir() if p.name.startswith(".build")] == []
    again = CliRunner().invoke(app, ["regenerate", str(copy), "-q"])
    assert again.exit_code == 0, again.output
    mesh, ref = TaggedMesh.load(copy / "build" / "mesh.npz"), TaggedMesh.load(design / "build" / "mesh.npz")
    assert np.array_equal(mesh.vertices, ref.vertices) and mesh.tag_table == ref.tag_table


@pytest.mark.slow
@pytest.mark.parametrize("seed", seeds("compare-signal", 6))
def test_signal_in_compare(seed, reference, tmp_path, monkeypatch):
    """compare of two results folders stopped at a seeded phase: no half compare.json; run again, the same."""
    import json

    from lensmount.cli import app
    from lensmount.loop import compare

    old, new = tmp_path / "old", tmp_path / "new"
    shutil.copytree(reference.out, old)
    shutil.copytree(reference.out, new)
    argv = ["compare", str(old), str(new), "--out", str(tmp_path / "cmp")]
    straight = CliRunner().invoke(app, argv + ["--out", str(tmp_path / "straight")])
    assert straight.exit_code == 0, straight.output
    rng = random.Random(seed)
    owner, name = rng.choice([(compare, "read_summary"), (compare, "read_exr"), (compare, "write_difference"),
                              (compare, "write_summary")])
    k, signum = rng.randint(1, 2 if name.startswith("read") else 1), rng.choice([signal.SIGINT, signal.SIGTERM])
    fired: list = []
    arm(monkeypatch, owner, name, k, signum, fired)
    result = CliRunner().invoke(app, argv)
    monkeypatch.undo()
    record(f"compare: {signal.Signals(signum).name} at call {k} of {name} (seed {seed})")
    assert fired and result.exit_code == (143 if signum == signal.SIGTERM else 130), result.output
    assert "Traceback" not in result.output
    _no_half_files(tmp_path / "cmp")
    again = CliRunner().invoke(app, argv)
    assert again.exit_code == 0, again.output

    def verdict(folder):
        doc = json.loads((folder / "compare.json").read_text())
        return {k: v for k, v in doc.items() if "path" not in k and "folder" not in k and k not in ("out", "sha256")}

    assert verdict(tmp_path / "cmp") == verdict(tmp_path / "straight")


@pytest.mark.slow
def test_signal_in_sweep(design, reference, tmp_path, monkeypatch):
    """A sweep stopped in its second variant says so; run again, its first variant is the reference run."""
    import csv

    from lensmount.analysis.passes import Accumulator
    from lensmount.cli import app
    from lensmount.run.executor import InProcess

    out = tmp_path / "sweep"
    argv = ["sweep", str(design), "--scene", str(design / "scenes" / "tiny.toml"), "--param", "scene.run.seed=1,2",
            "--out", str(out), *RUN]
    fired: list = []
    arm(monkeypatch, InProcess, "start", 2, signal.SIGTERM, fired)  # the second variant's passes begin
    result = CliRunner().invoke(app, argv)
    monkeypatch.undo()
    record("sweep: SIGTERM as the second variant starts tracing")
    assert fired and result.exit_code == 143, result.output
    assert "Traceback" not in result.output and result.output.strip().splitlines()[-1].startswith("SIGTERM")
    assert not (out / "sweep.csv").exists()
    again = CliRunner().invoke(app, argv)
    assert again.exit_code == 0, again.output
    first = Accumulator.load(out / "variants" / "00" / "run" / "checkpoint.npz")[0]
    assert first.pass_flux == reference.pass_flux
    assert len(list(csv.DictReader((out / "sweep.csv").open()))) == 2
