"""Flat bevel: a meniscus whose faces close in toward the rim gets its convex face flat from the
clear semi-diameter out, so that its edge is thick enough for a seat outside the light.

The lens: R 20 / R 60 mm positive meniscus, 1.4 mm thick, clear semi-diameter 8 mm (given).
By the sphere's sag its edge is 0.266 mm at 8 mm and thinner beyond; flat from 8 mm, the front
stays at its 8 mm sag while the rear keeps curving back, so the edge grows outward.
"""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app

LENS = """name = "thin positive meniscus"
aperture = { entrance_pupil_diameter = 14.0 }

[wavelengths]
values_um = [0.5876]

[field]
angles_deg = [0.0, 5.0]

[[surface]]
radius = "inf"
thickness = 5.0
stop = true

[[surface]]
radius = 20.0
thickness = 1.4
material = "1.5168/64.17"
clear_semi_diameter = 8.0

[[surface]]
radius = 60.0
thickness = 55.0
clear_semi_diameter = 8.0
"""


def _sag(radius: float, h: float) -> float:
    return radius - math.copysign(math.sqrt(radius * radius - h * h), radius)


@pytest.mark.slow  # init, regenerate (CAD), STEP re-import and a tiny simulate: ~15 s on the shared machine
def test_thin_meniscus_gets_a_flat_bevel_that_builds_and_simulates(tmp_path):
    lens = tmp_path / "lens.toml"
    lens.write_text(LENS)
    design = tmp_path / "design"
    assert CliRunner().invoke(app, ["init", str(design), "--lens", str(lens)]).exit_code == 0
    mount = tomllib.loads((design / "mount.toml").read_text())
    b, min_t = mount["lens_edge"]["chamfer_mm"], mount["checks"]["min_thickness_mm"]
    R = mount["lens_edge"]["semi_diameter_mm"]["1"]
    # by hand: no rim of the lens as ground (both faces to the edge) is thick enough ...
    for r in np.linspace(8.0, 10.0, 21):
        assert 1.4 + _sag(60.0, r) - _sag(20.0, r) - 2 * b < min_t
    # ... the flat-bevelled one is, at the radius init chose
    edge = 1.4 + _sag(60.0, R) - _sag(20.0, 8.0) - 2 * b
    assert edge >= min_t

    reg = CliRunner().invoke(app, ["regenerate", str(design), "--quiet"])
    assert reg.exit_code == 0, reg.output
    manifest = json.loads((design / "build" / "manifest.json").read_text())
    note = next(n for n in manifest["notes"] if n.startswith("lens-1: flat bevel"))
    assert "front face flat from 8.000 mm" in note and f"{edge:.3f} mm thick" in note

    import cadquery as cq

    part = next(p for p in manifest["parts"] if p["name"] == "lens-1")
    shape = cq.importers.importStep(str(design / "build" / part["step"])).val()
    assert shape.isValid()
    # the glass volume from the profile drawn by hand: cap to 8 mm then flat, 45° chamfers, rear face
    from lensmount.cad.layout import plan
    from lensmount.design.folder import load_design

    d = load_design(design)
    assert plan(d.prescription, d.mount).part("lens-1").template.front_flat_from == 8.0
    r = np.linspace(0.0, R, 20001)
    front = np.array([_sag(20.0, min(x, 8.0)) for x in r])
    back = 1.4 + np.array([_sag(60.0, x) for x in r])
    front = np.where(r > R - b, front + (r - (R - b)), front)
    back = np.where(r > R - b, back - (r - (R - b)), back)
    volume = 2 * np.pi * np.trapezoid((back - front) * r, r)
    assert shape.Volume() == pytest.approx(volume, rel=2e-4)

    sim = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / "case2-lambertian.toml"),
                                   "--photons-per-pass", "2000", "--passes", "2", "--workers", "1",
                                   "--out", str(tmp_path / "run")])
    assert sim.exit_code == 0, sim.output
