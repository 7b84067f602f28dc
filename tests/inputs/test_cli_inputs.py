"""Inputs that could change the answer silently, through `lensmount simulate`:
each is one paragraph naming the file, field and line, exit 2 and nothing written; or, where the
input is legal but suspicious, a warning printed and recorded in summary.json."""

from __future__ import annotations

import json
import re
import shutil

from tests.inputs.conftest import EXAMPLES, edit, simulate, wrote_nothing


def _one_paragraph(res) -> str:
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and res.output.rstrip().endswith(errors[0]), res.output  # one paragraph, last
    return errors[0]


def test_misspelt_selector_lists_what_the_mesh_holds(cooke):
    design, out = cooke
    finishes = design / "finishes.toml"
    line = edit(finishes, '"role:diaphragm-edge"', '"role:diafragm-edge"')
    text = _one_paragraph(simulate(design, out))
    assert str(finishes) in text and f"line {line}" in text and "field 'assign.role:diafragm-edge'" in text
    assert "matches no face" in text and "did you mean 'role:diaphragm-edge'" in text
    # What exists: the parts, roles, kinds and finishes of the cooke-triplet mesh.
    for word in ("part: ", "barrel", "lens-1", "housing", "role: ", "diaphragm-edge", "lens-edge",
                 "kind: ", "retainer", "finish: ", "black-anodised", "ground-glass"):
        assert word in text, word
    assert not out.exists()  # refused after the folder was checked: not even an empty --out is left


def test_undefined_mount_finish_names_mount_toml_field_and_line(cooke):
    design, out = cooke
    mount = design / "mount.toml"
    text = mount.read_text().replace("[barrel]\n", '[barrel]\nfinish = "black-anodized"\n', 1)
    mount.write_text(text)
    line = text.splitlines().index('finish = "black-anodized"') + 1
    msg = _one_paragraph(simulate(design, out))
    assert str(mount) in msg and f"line {line}" in msg and "field 'barrel.finish'" in msg
    assert "'black-anodized' is not defined" in msg and "did you mean 'black-anodised'" in msg
    assert "absorber, black-anodised" in msg  # the defined finishes are listed
    assert not out.exists()  # found before the regenerate: nothing written at all


def test_mount_finish_for_a_part_that_does_not_exist(cooke_built):
    """Checked against the regenerated assembly's parts (here directly: an edited mount.toml
    would cost a rebuild)."""
    import pytest

    from lensmount.mesh import TaggedMesh
    from lensmount.design.mount import check_finish_parts, parse_mount
    from lensmount.errors import InputError
    from lensmount.validation import parse_toml

    design, geometry = cooke_built
    parts = TaggedMesh.load(geometry / "mesh.npz").parts
    text = (design / "mount.toml").read_text() + '\n[finishes]\n"vane-7" = "mirror"\n'
    mount = parse_mount(parse_toml(text, "mount.toml"), file="mount.toml", text=text)
    with pytest.raises(InputError) as err:
        check_finish_parts(mount, parts)
    e = err.value
    assert e.field == "finishes.vane-7" and e.line == len(text.splitlines()) and "no part is named 'vane-7'" in e.detail
    assert "vane-1" in e.valid and "barrel" in e.valid
    check_finish_parts(parse_mount({"finishes": {"vane-1": "mirror"}}), parts)  # an existing part is fine


def test_mount_finish_defined_by_the_design_finishes_is_accepted():
    """A mount may name a label finishes.toml defines or re-assigns: not an error (the check can pass)."""
    from lensmount.design.finishes import Finishes
    from lensmount.design.mount import parse_mount
    from lensmount.design.finishes import check_mount_finishes
    from tests.inputs.conftest import FINISHES
    import tomllib

    mount = parse_mount({"barrel": {"finish": "matt-black"}}, file="mount.toml")
    data = tomllib.loads(FINISHES)
    check_mount_finishes(Finishes(**data | {"finishes": data["finishes"] | {"matt-black": {"model": "absorber"}}}),
                         mount)
    check_mount_finishes(Finishes(**data | {"assign": data["assign"] | {"finish:matt-black": "absorber"}}), mount)


def test_undefined_design_finish_names_the_line(cooke):
    design, out = cooke
    finishes = design / "finishes.toml"
    line = edit(finishes, '"*" = "absorber"', '"*" = "black-anodized"')
    msg = _one_paragraph(simulate(design, out))
    assert str(finishes) in msg and f"line {line}" in msg and "field 'assign.*'" in msg and "black-anodised" in msg
    assert wrote_nothing(out)


def test_a_scene_file_with_finishes_says_how_to_move_them(cooke):
    """The layout before finishes moved to the design: one paragraph naming the tables, the scene
    file and where they go (DESIGN/finishes.toml); exit 2, nothing written."""
    from tests.inputs.conftest import FINISHES

    design, out = cooke
    scene = design / "scenes" / "test.toml"
    scene.write_text(scene.read_text().replace("[run]", FINISHES + "\n[run]"))
    line = scene.read_text().splitlines().index("[finishes]") + 1
    msg = _one_paragraph(simulate(design, out))
    assert str(scene) in msg and f"line {line}" in msg and "field 'finishes'" in msg
    assert "[finishes], [assign]" in msg and f"into {design.absolute() / 'finishes.toml'}" in msg
    assert "delete them from every scene file" in msg
    assert wrote_nothing(out)


def test_lens_toml_and_lens_zmx_together_is_ambiguous(cooke):
    design, out = cooke
    shutil.copy2(EXAMPLES / "cooke-triplet" / "cooke-triplet.zmx", design / "lens.zmx")
    msg = _one_paragraph(simulate(design, out))
    assert str(design) in msg and "both lens.toml and lens.zmx" in msg and "exactly one lens file" in msg
    assert wrote_nothing(out)


def test_misspelt_scene_key_is_unknown_not_missing(cooke):
    design, out = cooke
    scene = design / "scenes" / "test.toml"
    line = edit(scene, "off_axis_deg = 25.0", "off_axis_degree = 25.0")
    msg = _one_paragraph(simulate(design, out))
    assert "unknown key 'off_axis_degree'" in msg and "did you mean 'off_axis_deg'" in msg
    assert f"line {line}" in msg and "field 'source.off_axis_degree'" in msg
    assert "required" not in msg
    assert "type, off_axis_deg, azimuth_deg" in msg  # the keys allowed in [source]
    assert wrote_nothing(out)


def test_mount_errors_carry_line_numbers(cooke):
    design, out = cooke
    mount = design / "mount.toml"
    line = edit(mount, "land_mm = 0.05", "land_mm = -0.05")
    msg = _one_paragraph(simulate(design, out))
    assert str(mount) in msg and f"line {line}" in msg and "field 'diaphragm.land_mm'" in msg and "> 0" in msg
    assert not out.exists()


def test_detector_larger_than_the_housing_is_a_recorded_warning(cooke):
    design, out = cooke
    scene = design / "scenes" / "test.toml"
    edit(scene, "width_mm = 36.0\nheight_mm = 24.0", "width_mm = 44.5\nheight_mm = 44.5")
    res = simulate(design, out)
    assert res.exit_code == 0, res.output
    printed = " ".join(res.output.split())  # the terminal may wrap the line
    assert re.search(r"warning: the detector \(44\.5 × 44\.5 mm.* is larger than the housing", printed), printed
    warnings = json.loads((out / "summary.json").read_text())["warnings"]
    assert len(warnings) == 1 and "44.5 × 44.5 mm" in warnings[0] and "housing" in warnings[0]


def test_housing_bore_is_the_one_built_for_the_detector(cooke_built):
    """The bore found in the mesh is the housing's (detector corners + clearance, from mount.toml),
    so a detector of the size the housing was built for gives no warning and a larger one does."""
    import math

    from lensmount.mesh import TaggedMesh
    from lensmount.design.folder import load_design
    from lensmount.scene.build import detector_warnings, housing_bore_at
    from lensmount.physics.detector import Detector

    design, geometry = cooke_built
    mesh = TaggedMesh.load(geometry / "mesh.npz")
    d = load_design(design)
    h, z = d.mount.housing, d.prescription.image_z
    corner = 0.5 * math.hypot(h.detector_width_mm, h.detector_height_mm)
    bore = housing_bore_at(mesh, z)
    assert corner < bore <= corner + h.detector_clearance_mm + 1e-6
    assert detector_warnings(mesh, Detector(h.detector_width_mm, h.detector_height_mm, 4, 4, z)) == []
    assert len(detector_warnings(mesh, Detector(44.5, 44.5, 4, 4, z))) == 1
