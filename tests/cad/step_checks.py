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
