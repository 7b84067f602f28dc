"""Every file the tool reads, damaged (truncated, emptied, one bit flipped): one paragraph that
names the file and says what to do (exit 2), or — where the damage cannot change what is read —
exactly what an undamaged file gives. Never a traceback, never other numbers.

The seeds are fixed per kind (injection.seeds); a failing case's id is its seed, and the
recorded description says which byte and bit were hit.
"""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from injection import damage, seeds
from fault_log import record
from lensmount.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "src" / "lensmount" / "examples" / "cooke-triplet"
TINY_SCENE = (EXAMPLE / "scenes" / "case1-diaphragm-edge.toml").read_text().replace("pixels = [360, 240]",
                                                                                    "pixels = [36, 24]")
FAST = 4  # the first seeds of each kind run in the fast suite, the rest are marked slow


def some(kind: str, n: int):
    """pytest params: n seeds of this kind, the first FAST unmarked and the rest slow."""
    return [pytest.param(s, id=f"seed{s}", marks=() if i < FAST else pytest.mark.slow)
            for i, s in enumerate(seeds(kind, n))]


def one_paragraph(result, path: Path) -> str:
    """The CLI's answer to a damaged file: exit 2 and one paragraph naming it, no traceback."""
    assert result.exit_code == 2, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and str(path.name) in errors[0], result.output  # progress lines may come before
    return errors[0]


@pytest.fixture(scope="module")
def design(tmp_path_factory) -> Path:
    """The Cooke triplet with a 36 × 24 pixel case 1 (nothing built: these cases stop before the build)."""
    folder = tmp_path_factory.mktemp("design") / "cooke-triplet"
    shutil.copytree(EXAMPLE, folder)
    (folder / "scenes" / "tiny.toml").write_text(TINY_SCENE)
    return folder


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    """A real checkpoint: three passes of the planar scene (tests/run/planar_run.py)."""
    ck = tmp_path_factory.mktemp("ck") / "checkpoint.npz"
    subprocess.run([sys.executable, str(ROOT / "tests" / "run" / "planar_run.py"), str(ck), "3", "1"],
                   check=True, capture_output=True, timeout=300)
    return ck


# -- checkpoint.npz -------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", some("checkpoint", 40))
def test_damaged_checkpoint(seed, checkpoint, design, tmp_path):
    from lensmount.analysis.passes import Accumulator
    from lensmount.cli import app

    whole, _ = Accumulator.load(checkpoint)
    out = tmp_path / "out"
    out.mkdir()
    target = out / "checkpoint.npz"
    shutil.copy(checkpoint, target)
    damage(target, seed)
    try:
        acc, _ = Accumulator.load(target)
    except InputError as error:
        assert error.file == str(target)
    else:  # the flip hit bytes nothing reads (a zip header's spare field): the same state, bit for bit
        assert acc.pass_flux == whole.pass_flux and np.array_equal(acc.sum_image, whole.sum_image)
    # through the command line: refused before anything is built (also a checkpoint that loads,
    # because it belongs to another run), one paragraph naming it
    result = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / "tiny.toml"),
                                      "--resume", "--out", str(out), "--no-record", "--workers", "1"])
    one_paragraph(result, target)
    assert sorted(p.name for p in out.iterdir()) == ["checkpoint.npz"]  # nothing else written


@pytest.mark.parametrize("how", ["truncate", "zero bytes"])
def test_truncated_and_empty_checkpoint_say_so(how, checkpoint, design, tmp_path):
    from lensmount.cli import app

    target = tmp_path / "checkpoint.npz"
    shutil.copy(checkpoint, target)
    damage(target, 1, how)
    result = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / "tiny.toml"),
                                      "--resume", "--out", str(tmp_path), "--no-record"])
    text = one_paragraph(result, target)
    assert "damaged" in text and "--resume" in text


# -- the design's own files ----------------------------------------------------------------------

@pytest.mark.parametrize("seed", some("design", 60))
def test_damaged_design_file(seed, design, tmp_path):
    import random

    from lensmount.loop.prepare import read_inputs

    copy = tmp_path / "design"
    shutil.copytree(design, copy)
    rng = random.Random(seed)
    choice = rng.choice(["lens.toml", "mount.toml", "scenes/tiny.toml", "lens.zmx"])
    if choice == "lens.zmx":  # a design whose lens is the Zemax file
        (copy / "lens.toml").unlink()
        shutil.move(copy / "cooke-triplet.zmx", copy / "lens.zmx")
    target = copy / choice
    damage(target, seed)
    try:
        read_inputs(copy, copy / "scenes" / "tiny.toml")
    except InputError as error:
        assert error.paragraph()
        assert Path(error.file or "").name == target.name or target.name in error.paragraph(), error.paragraph()


# -- summary.json ---------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", some("summary", 25))
def test_damaged_summary(seed, tmp_path):
    from lensmount.loop.compare import Run
    from lensmount.run.results import write_summary
    from tests.loop.runs import write_run

    whole = write_run(tmp_path, 1.5e-6, 2e-7)
    write_summary(tmp_path / "summary.json", whole)  # as simulate writes it: with its checksum
    damage(tmp_path / "summary.json", seed)
    try:
        run = Run.load(tmp_path, "A")
    except InputError as error:
        assert error.file == str(tmp_path / "summary.json")
    else:  # only a flip in the indentation's whitespace can leave it whole
        assert run.summary == whole


# -- the results store ----------------------------------------------------------------------------

def _store_with_runs(folder: Path) -> tuple[Path, list]:
    from lensmount.run.store import Store
    from tests.loop.runs import paths, write_run

    db = folder / "runs.sqlite"
    with Store(db) as store:
        for k in range(3):
            store.record(write_run(folder / f"r{k}", 1e-6 * (k + 1), 1e-7), paths(folder / f"r{k}"))
        rows = store.runs()
    return db, rows


@pytest.mark.parametrize("seed", some("store", 25))
def test_damaged_store(seed, tmp_path):
    from lensmount.run.store import Store

    db, rows = _store_with_runs(tmp_path)
    damage(db, seed)
    try:
        with Store(db) as store:
            again = store.runs()
    except InputError as error:
        assert error.file == str(db) and ("damaged" in error.detail or "cannot open" in error.detail)
    else:  # a flip in a free page or an unused header byte
        assert again == rows


def test_locked_store_says_so(tmp_path, monkeypatch):
    from lensmount.run import store as store_module
    from tests.loop.runs import paths, write_run

    db, _ = _store_with_runs(tmp_path)
    holder = sqlite3.connect(db, isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")  # another process writing, and not letting go
    record("runs.sqlite: write lock held by another connection")
    monkeypatch.setattr(store_module, "BUSY_TIMEOUT_MS", 200)
    try:
        with store_module.Store(db) as store, pytest.raises(InputError) as caught:
            store.record(write_run(tmp_path / "r9", 1e-6, 1e-7), paths(tmp_path / "r9"))
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert "locked" in caught.value.detail and caught.value.file == str(db)


# -- mesh.npz and regenerate's build folder ---------------------------------------------------------

@pytest.fixture(scope="module")
def mesh_file(tmp_path_factory) -> Path:
    from lensmount.mesh import FaceTag, TaggedMesh

    rng = np.random.default_rng(0)
    tags = [FaceTag("barrel", "barrel", "inner-wall", "black", -1, k) for k in range(3)]
    mesh = TaggedMesh(rng.random((30, 3)), rng.integers(0, 30, (40, 3)), rng.integers(0, 3, 40).astype(np.int32),
                      tags)
    path = tmp_path_factory.mktemp("mesh") / "mesh.npz"
    mesh.save(path)
    return path


@pytest.mark.parametrize("seed", some("mesh", 20))
def test_damaged_mesh(seed, mesh_file, tmp_path):
    from lensmount.mesh import TaggedMesh

    whole = TaggedMesh.load(mesh_file)
    target = tmp_path / "mesh.npz"
    shutil.copy(mesh_file, target)
    damage(target, seed)
    try:
        mesh = TaggedMesh.load(target)
    except InputError as error:
        assert error.file == str(target)
    else:
        assert np.array_equal(mesh.vertices, whole.vertices) and mesh.tag_table == whole.tag_table


@pytest.mark.slow
def test_damaged_numba_cache_is_compiled_again(tmp_path):
    """A kernel's cache files truncated or emptied: compiled again, the same answer, no traceback."""
    module = tmp_path / "kernel_mod.py"
    module.write_text("from numba import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    script = ("import sys; sys.path.insert(0, sys.argv[1]); import kernel_mod\n"
              "from lensmount.trace.jit_cache import drop_damaged\n"
              "print(drop_damaged(vars(kernel_mod)), kernel_mod.twice(21))\n")
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}
    run = [sys.executable, "-c", script, str(tmp_path)]
    first = subprocess.run(run, capture_output=True, text=True, env=env, timeout=300)
    assert first.returncode == 0 and first.stdout.split()[-1] == "42", first.stderr
    for k, how in enumerate(["zero bytes", "truncate"]):
        for data in sorted((tmp_path / "cache").rglob("*.nbc")):
            damage(data, k, how)
        again = subprocess.run(run, capture_output=True, text=True, env=env, timeout=300)
        assert again.returncode == 0 and "Traceback" not in again.stderr, again.stderr
        assert again.stdout.split()[-1] == "42" and "twice" in again.stdout  # dropped, compiled, right
