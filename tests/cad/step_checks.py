"""The machine-shop check shared by the corpus tests: CadQuery (an independent STEP reader)
re-imports every part of a regenerate folder as one valid solid of the volume the manifest
records, and the assembly as one solid per part."""

from __future__ import annotations

import json
from pathlib import Path

import pytest


def assert_step_parts_valid(build: Path, min_parts: int = 2) -> dict:
    """Check `build` (a regenerate folder); return its manifest."""
    import cadquery as cq

    manifest = json.loads((build / "manifest.json").read_text())
    assert len(manifest["parts"]) >= min_parts
    for part in manifest["parts"]:
        shape = cq.importers.importStep(str(build / part["step"])).val()
        assert shape.isValid() and shape.Volume() == pytest.approx(part["volume_mm3"], rel=1e-6), part["name"]
    assert len(cq.importers.importStep(str(build / "assembly.step")).solids().vals()) == len(manifest["parts"])
    return manifest


def assert_case2_simulates(design: Path, out: Path, photons_per_pass: int) -> dict:
    """The design's starter case-2 scene (from `init --lens`), on a detector a tenth the pixels,
    simulates with exit 0 and every number of its summary finite; returns the summary."""
    import math
    import tomllib

    import tomli_w
    from typer.testing import CliRunner

    from lensmount.cli import app

    scene = design / "scenes" / "case2-lambertian.toml"
    doc = tomllib.loads(scene.read_text())
    doc["detector"]["pixels"] = [max(1, n // 10) for n in doc["detector"]["pixels"]]
    scene.write_text(tomli_w.dumps(doc))
    sim = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(scene), "--photons-per-pass",
                                   str(photons_per_pass), "--passes", "2", "--workers", "1", "--out", str(out)])
    assert sim.exit_code == 0, sim.output
    summary = json.loads((out / "summary.json").read_text())
    assert all(math.isfinite(v) for v in _numbers(summary))
    return summary


def _numbers(tree):
    if isinstance(tree, dict):
        for v in tree.values():
            yield from _numbers(v)
    elif isinstance(tree, list):
        for v in tree:
            yield from _numbers(v)
    elif isinstance(tree, float):
        yield tree
