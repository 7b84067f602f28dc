"""The cooke-triplet example as a user gets it (`lensmount init`), its geometry regenerated
once per session into DESIGN/build (where simulate looks); each test copies the folder with
it, so a test that edits an input pays no rebuild unless the edit changes the CAD."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lensmount.cli import app

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"

# A scene for the cooke triplet's 36 × 24 mm housing, small enough to run in a second.
SCENE = """\
description = "cooke triplet, the sun at 25°"

[source]
type = "sun"
off_axis_deg = 25.0
azimuth_deg = 90.0

[detector]
width_mm = 36.0
height_mm = 24.0
pixels = [12, 8]

[run]
photons = 2000
passes = 1
seed = 1
"""

# The design's finishes for these tests (DESIGN/finishes.toml): case 1's, only the diaphragm edge scatters.
FINISHES = """\
[finishes]
edge-lambert-10 = { model = "lambertian", reflectance = 0.10 }

[assign]
"*" = "absorber"
"role:diaphragm-edge" = "edge-lambert-10"
"""

OUTPUTS = ("summary.json", "irradiance.exr", "preview.png", "checkpoint.npz")


@pytest.fixture(scope="session")
def cooke_built(tmp_path_factory):
    """(design folder, its geometry folder DESIGN/build) of `lensmount init -e cooke-triplet`,
    regenerated once."""
    from lensmount.cad.pipeline import regenerate

    base = tmp_path_factory.mktemp("cooke")
    design = base / "design"
    res = CliRunner().invoke(app, ["init", str(design), "--example", "cooke-triplet"])
    assert res.exit_code == 0, res.output
    regenerate(design, design / "build")
    return design, design / "build"


@pytest.fixture
def cooke(cooke_built, tmp_path):
    """A fresh copy of the design (with its cached geometry in build/, finishes.toml = FINISHES and
    scenes/test.toml) and an out folder that does not exist yet."""
    design, _ = cooke_built
    mine = tmp_path / "design"
    shutil.copytree(design, mine)
    (mine / "scenes").mkdir(exist_ok=True)
    (mine / "scenes" / "test.toml").write_text(SCENE)
    (mine / "finishes.toml").write_text(FINISHES)
    return mine, tmp_path / "out"


def simulate(design: Path, out: Path, *extra: str):
    """Run `lensmount simulate` on scenes/test.toml; returns the click Result."""
    args = ["simulate", str(design), "--scene", str(design / "scenes" / "test.toml"), "--out", str(out),
            "--method", "forward", "--workers", "1", *extra]
    return CliRunner().invoke(app, args)


def edit(path: Path, old: str, new: str) -> int:
    """Replace `old` (once) in a file; returns the 1-based line of the edit."""
    text = path.read_text()
    assert old in text, f"{old!r} not in {path}"
    path.write_text(text.replace(old, new, 1))
    return text[: text.index(old)].count("\n") + 1


def wrote_nothing(out: Path) -> bool:
    return not any((out / name).exists() for name in OUTPUTS)
