"""Shared fixtures: the reference design regenerated once per session."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


def copy_design(name: str, dest: Path) -> Path:
    dest.mkdir(parents=True, exist_ok=True)
    for f in ("lens.toml", "mount.toml"):
        shutil.copy2(EXAMPLES / name / f, dest / f)
    return dest


@pytest.fixture(scope="session")
def examples_dir() -> Path:
    return EXAMPLES


@pytest.fixture(scope="session")
def design_copier():
    """copy_design(example name, destination) -> destination."""
    return copy_design


@pytest.fixture(scope="session")
def reference(tmp_path_factory):
    """(design dir, out dir, Manifest) of examples/double-gauss-360, built once."""
    from lensmount.cad.pipeline import regenerate

    base = tmp_path_factory.mktemp("dg360")
    design = copy_design("double-gauss-360", base / "design")
    out = base / "out"
    manifest = regenerate(design, out)
    return design, out, manifest


@pytest.fixture(scope="session")
def reference_layout():
    """Layout of the reference lens with the reference mount (no CAD kernel)."""
    from lensmount.cad.layout import plan
    from lensmount.design.lens import load_lens
    from lensmount.design.mount import load_mount

    p = load_lens(EXAMPLES / "double-gauss-360" / "lens.toml")
    spec = load_mount(EXAMPLES / "double-gauss-360" / "mount.toml")
    return plan(p, spec), spec


@pytest.fixture(scope="session")
def reference_mesh(reference):
    from lensmount.mesh import TaggedMesh

    _, out, _ = reference
    return TaggedMesh.load(out / "mesh.npz")


@pytest.fixture(scope="session")
def cooke(tmp_path_factory):
    """(design dir, out dir) of examples/cooke-triplet, made by `lensmount init` + `regenerate` once."""
    from typer.testing import CliRunner

    from lensmount.cli import app

    base = tmp_path_factory.mktemp("cooke")
    design, out = base / "cooke", base / "out"
    runner = CliRunner()
    res = runner.invoke(app, ["init", str(design), "--example", "cooke-triplet"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["regenerate", str(design), "--out", str(out), "--quiet"])
    assert res.exit_code == 0, res.output
    return design, out
