"""The cold-stop style rear baffle (`[housing] rear_baffle = true`): a tube in the detector
housing from the barrel to just before the image plane whose bore follows the beam. Layout
level (no CAD kernel): its bore clears the real-ray envelope everywhere by the margin's
chord rule, it touches the barrel and sits in the housing, the layout checks pass. The slow
test builds it into STEP and sees it in the mesh and in `check`."""

import sys
from pathlib import Path

import numpy as np
import pytest

from lensmount.cad.checks import check_layout
from lensmount.cad.layout import plan
from lensmount.design.lens import load_lens
from lensmount.design.mount import parse_mount
from lensmount.optics.apertures import beam_envelope

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_outer_stops import MOUNT, two_singlets  # noqa: E402


def _singlets(tmp_path, **housing):
    d = two_singlets(tmp_path / "rear", "rear")
    mount = dict(MOUNT, housing=dict(MOUNT["housing"], **housing))
    spec = parse_mount(mount)
    return plan(load_lens(d / "lens.toml"), spec), spec


def test_rear_baffle_bore_follows_the_beam(tmp_path):
    """Two singlets converging onto a 3 mm detector: the bore clears the real-ray envelope
    by the margin everywhere between its samples and stays within half a millimetre of that."""
    layout, spec = _singlets(tmp_path, rear_baffle=True)
    baffle = layout.part("rear-baffle")
    assert baffle.kind == "baffle"
    t = baffle.template
    image_z = layout.prescription.image_z
    assert t.z_back == pytest.approx(image_z - spec.housing.rear_baffle_gap_mm)
    # the bore (straight between its samples) against the real-ray envelope, densely and independently
    zs = np.linspace(t.z_front, t.z_back, 120)
    bore = np.interp(zs, [z for _, z in t.bore], [r for r, _ in t.bore])
    beam = beam_envelope(layout.prescription, zs)
    assert (bore - beam).min() >= spec.housing.rear_baffle_margin_mm - 1e-6
    assert (bore - beam).max() < spec.housing.rear_baffle_margin_mm + 0.5  # it follows the beam, not a wide tube
    housing = layout.part("housing").template
    assert t.outer_radius == pytest.approx(housing.inner_radius - spec.spacers.radial_clearance_mm)
    assert t.outer_radius - max(r for r, _ in t.bore) >= spec.housing.rear_baffle_wall_mm - 1e-9
    barrel_back = max(z for _, z in layout.part("barrel").template.bore)
    assert t.z_front == pytest.approx(barrel_back + (housing.wall if housing.flange_radius is not None else 0.0))
    check_layout(layout, spec, {pp.name: pp.template.segments() for pp in layout.parts})


def test_no_rear_baffle_without_a_housing(tmp_path):
    from lensmount.errors import GeometryError

    with pytest.raises(GeometryError, match="housing"):
        _singlets(tmp_path, rear_baffle=True, enabled=False)


@pytest.mark.slow
def test_rear_baffle_regenerates_into_valid_step_and_check_sees_it(tmp_path, design_copier):
    """Valid STEP, a mesh part of kind baffle (so the integrators trace it), the beam clear
    (regenerate's checks), and `check` with the sun just outside the field finds the sun's
    image on the rear baffle's bore, where it had been on the housing's."""
    import json

    from build123d import import_step
    from typer.testing import CliRunner

    from lensmount.mesh import TaggedMesh
    from lensmount.cli import app

    d = design_copier("double-gauss-360", tmp_path / "d")
    text = (d / "mount.toml").read_text().replace("[housing]\n", "[housing]\nrear_baffle = true\n")
    (d / "mount.toml").write_text(text)
    res = CliRunner().invoke(app, ["regenerate", str(d), "--quiet"])
    assert res.exit_code == 0, res.output
    step = import_step(d / "build" / "parts" / "rear-baffle.step")
    assert step.is_valid and step.volume > 0
    mesh = TaggedMesh.load(d / "build" / "mesh.npz")
    assert any(t.part == "rear-baffle" and t.kind == "baffle" for t in mesh.tag_table)
    assert (d / "build" / "parts" / "rear-baffle.dxf").is_file()
    res = CliRunner().invoke(app, ["check", str(d), "--exclusion-deg", "5.5"])
    doc = json.loads((d / "build" / "check" / "check.json").read_text())
    parts = {w["part"] for w in doc["lit_walls_seen"]}
    assert "rear-baffle" in parts, res.output
