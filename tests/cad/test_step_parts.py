"""Parts from the user's STEP files ([parts.NAME] in mount.toml), checked like generated parts.

The housing the tests bring is the reference design's own generated housing (the same solid),
written as a mechanical CAD program writes STEP: a product name, named faces and two colours
(`step_writer`). So what the pipeline makes of it can be checked against what the test wrote,
and against the generated housing it replaces."""

from __future__ import annotations

import json
import math
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.errors import GeometryError, InputError

from tests.cad.step_writer import write_step

DARK, LIGHT = "#1a1a1a", "#c8c8c8"
COLOUR_FINISH = {DARK: "absorber", LIGHT: "black-anodised"}
ROOT = Path(__file__).resolve().parents[2]


def face_plan(solid, image_z: float):
    """(names, colours) the test gives the housing's faces: the bore and the back wall's inside
    (the faces the light sees) dark, the rest light; each named by what it is."""
    names, colours = {}, {}
    for k, f in enumerate(solid.faces()):
        p, n = f.position_at(0.5, 0.5), f.normal_at(0.5, 0.5)
        radial = (p.X * n.X + p.Y * n.Y) / max(math.hypot(p.X, p.Y), 1e-12)
        if f.geom_type.name == "CYLINDER":
            names[k] = "bore" if radial < 0 else "outside"
        else:
            names[k] = ("back-wall" if p.Z > image_z else "front") if n.Z < 0 else "back"
        colours[k] = DARK if names[k] in ("bore", "back-wall") else LIGHT
    return names, colours


def make_design(base: Path, entry: str, solids=None, unit="MM", scenes=True) -> Path:
    """The reference design with the STEP housing (`solids` for write_step, default the generated
    housing named and coloured by face_plan) and `entry` appended to mount.toml."""
    from lensmount.cad.layout import plan
    from lensmount.design.lens import load_lens
    from lensmount.design.mount import load_mount

    ex = ROOT / "examples" / "double-gauss-360"
    base.mkdir(parents=True, exist_ok=True)
    for f in ("lens.toml", "mount.toml"):
        shutil.copy2(ex / f, base / f)
    # The design's treatment without its "*" rule: the generated parts keep their mount finishes (the
    # STEP part's faces keep the finishes its colours and names give them either way).
    treatment = (ex / "finishes.toml").read_text()
    (base / "finishes.toml").write_text("\n".join(line for line in treatment.splitlines()
                                                 if not line.startswith('"*"')) + "\n")
    if scenes:
        shutil.copytree(ex / "scenes", base / "scenes")
    if solids is None:
        layout = plan(load_lens(ex / "lens.toml"), load_mount(ex / "mount.toml"))
        housing = layout.part("housing").template.build()
        names, colours = face_plan(housing, layout.prescription.image_z)
        solids = [("mechanical-housing", housing, names, colours, {})]
    write_step(base / "housing.step", solids, unit)
    with open(base / "mount.toml", "a") as f:
        f.write("\n" + entry)
    return base


ENTRY = f'''[parts.housing]
step = "housing.step"
unit = "mm"
colours = {{ "{DARK}" = "absorber", "{LIGHT}" = "black-anodised" }}
names = {{ "back" = "ground-glass" }}
'''


@pytest.fixture(scope="module")
def step_housing(tmp_path_factory):
    """(design, out, manifest) of the reference with the STEP housing, regenerated once."""
    from lensmount.cad.pipeline import regenerate

    design = make_design(tmp_path_factory.mktemp("step-housing") / "design", ENTRY)
    return design, design / "build", regenerate(design)


def test_the_step_housing_replaces_the_generated_one_face_by_face(step_housing, reference_layout):
    from build123d import import_step

    from lensmount.mesh import TaggedMesh

    design, out, manifest = step_housing
    layout, _ = reference_layout
    generated = layout.part("housing").template.build()
    names, colours = face_plan(generated, layout.prescription.image_z)
    housing = [p for p in manifest.parts if p.name == "housing"]
    assert len(housing) == 1 and housing[0].kind == "housing"
    assert housing[0].volume_mm3 == pytest.approx(generated.volume, rel=1e-9)
    mesh = TaggedMesh.load(out / "mesh.npz")
    tags = [t for t in mesh.tag_table if t.part == "housing"]
    assert sorted(t.face for t in tags) == list(range(len(names)))
    for t in tags:  # the STEP face index, its name, and the finish its colour (or its name) maps to
        assert t.label == names[t.face]
        assert t.finish == ("ground-glass" if names[t.face] == "back" else COLOUR_FINISH[colours[t.face]])
    assert {t.finish for t in tags} == {"absorber", "black-anodised", "ground-glass"}
    # round trip: the assembly holds the user's housing in place, and its drawing and face picture exist
    assembly = import_step(out / "assembly.step")
    placed = [c for c in assembly.children if c.label == "housing"]
    assert len(placed) == 1 and placed[0].volume == pytest.approx(generated.volume, rel=1e-6)
    assert placed[0].bounding_box().min.Z == pytest.approx(generated.bounding_box().min.Z, abs=1e-6)
    for f in (housing[0].svg, housing[0].dxf, "parts/housing.faces.png"):
        assert (out / f).stat().st_size > 0
    notes = " ".join(manifest.notes)
    assert "housing: from housing.step (mm)" in notes
    clearance = float(re.search(r"housing: clears the beam envelope by ([0-9.]+) mm", notes).group(1))
    assert clearance > 0.5  # the generated housing's bore clears the detector corners by 2 mm
    assert "field 5°: 0.00 %" in notes


def test_a_design_with_a_step_part_comes_from_the_cache_when_unchanged(step_housing):
    """Every file the build wrote (the face picture too) is what the cache check reads: a second
    regenerate with unchanged inputs, and a simulate or check after it, do not run the CAD kernel."""
    from lensmount.cad.pipeline import regenerate

    design, out, first = step_housing
    again = regenerate(design)
    assert again.cached and again.checksums == first.checksums
    assert "parts/housing.faces.png" in first.checksums
    res = CliRunner().invoke(app, ["regenerate", str(design), "--quiet"])
    assert res.exit_code == 0 and "from the cache (inputs unchanged)" in res.output, res.output
    # a damaged face picture is rebuilt, never served
    (out / "parts" / "housing.faces.png").write_bytes(b"damaged")
    assert not regenerate(design).cached
    assert regenerate(design).cached
    assert (out / "parts" / "housing.faces.png").read_bytes().startswith(b"\x89PNG")


def test_the_step_parts_own_face_finishes_outrank_a_star_rule_and_a_rule_deciding_nothing_is_said(
        step_housing, tmp_path):
    """finishes.toml's "*" paints the generated parts, not the faces mount.toml finished face by face;
    a part: rule whose every face has its own finish decides nothing, and the scene says so."""
    from lensmount.loop.prepare import prepare
    from lensmount.mesh import TaggedMesh

    design = Path(shutil.copytree(step_housing[0], tmp_path / "d"))
    (design / "finishes.toml").write_text((ROOT / "examples" / "double-gauss-360" / "finishes.toml").read_text()
                                          + '"part:housing" = "edge-lambert-10"\n')
    prepared = prepare(design, design / "scenes" / "case2-lambertian.toml")
    mesh = TaggedMesh.load(prepared.built.folder / "mesh.npz")
    finishes = dict(zip(mesh.tag_table, prepared.scene.finish_of_tag))
    housing = [t for t in mesh.tag_table if t.part == "housing"]
    assert housing and all(t.assigned for t in housing)
    assert [finishes[t] for t in housing] == [t.finish for t in housing]  # absorber, black-anodised, ground-glass
    assert {finishes[t] for t in mesh.tag_table if t.part == "barrel"} == {"black-paint"}
    [warning] = [w for w in prepared.scene.warnings if "part:housing" in w]
    assert "decides no face" in warning and "housing face" in warning and "by its colour" in warning


def test_a_face_rule_that_selects_no_face_is_refused_and_one_deciding_none_is_noted(tmp_path, reference_layout):
    from build123d import Cylinder

    from lensmount.cad.assembly import step_built_parts
    from lensmount.design.mount import parse_mount

    layout, spec = reference_layout
    path = write_step(tmp_path / "tube.step", [("tube", Cylinder(60.0, 40.0) - Cylinder(55.0, 40.0), {}, {}, {})])
    entry = {"step": "tube.step", "datum": "image-plane", "offset_mm": [0, 0, 30.0], "kind": "baffle",
             "allow_vignetting": True,
             "rules": [{"finish": "absorber", "r_min_mm": 54.0}, {"finish": "mirror", "normal": [0, 0, 1]}]}
    ok = parse_mount({**spec.model_dump(exclude={"parts"}), "parts": {"camera": entry}})
    noted = replace(layout, notes=[])
    [part] = step_built_parts(noted, ok, {"camera": path}, {}, set())
    assert set(part.face_finishes) == {"absorber"}  # every face of the tube lies at r >= 55 mm
    notes = " ".join(noted.notes)
    assert "camera: rule 2 (normal = (0.0, 0.0, 1.0), within_deg = 10.0) decides no face" in notes
    entry["rules"][0]["r_min_mm"] = 70.0  # outside the tube: no face
    bad = parse_mount({**spec.model_dump(exclude={"parts"}), "parts": {"camera": entry}})
    with pytest.raises(InputError) as err:
        step_built_parts(replace(layout, notes=[]), bad, {"camera": path}, {}, set())
    assert "parts.camera.rules.0" in str(err.value) and "selects no face" in str(err.value)


@pytest.mark.slow  # a whole case-2 run (~20 s); the STEP housing's faces and tags are checked in the fast tests above
def test_case2_simulates_and_paths_names_the_users_faces(step_housing, tmp_path):
    import tomllib

    import tomli_w

    design, _, _ = step_housing
    scene = design / "scenes" / "case2-lambertian.toml"
    doc = tomllib.loads(scene.read_text())
    doc["detector"]["pixels"] = [60, 60]
    doc["effects"]["scatter"] = True  # every face the design's finishes let scatter (its STEP faces too)
    tiny = design / "scenes" / "case2-tiny.toml"
    tiny.write_text(tomli_w.dumps(doc))
    out = tmp_path / "run"
    runner = CliRunner()
    res = runner.invoke(app, ["simulate", str(design), "--scene", str(tiny), "--photons-per-pass", "3000",
                              "--passes", "1", "--workers", "1", "--out", str(out), "--no-record"])
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    assert math.isfinite(summary["stray_fraction"]) if "stray_fraction" in summary else True
    assert "file.housing.step" in summary["provenance"]["design"]  # the STEP file is part of the revision
    res = runner.invoke(app, ["paths", str(out), "--faces", "--top", "200"])
    assert res.exit_code == 0, res.output
    assert "housing face" in res.output and "'bore'" in res.output, res.output


def test_a_hood_in_the_beam_reports_vignetting_per_field_and_stops_regenerate(tmp_path):
    """A tube in front of the lens whose bore is 0.8 of the entrance pupil's radius: on axis it
    stops the pupil's outer annulus, 1 − 0.8² = 36 % of it (the grid's sampling error ~2 %)."""
    from build123d import Cylinder, Pos

    from lensmount.design.lens import load_lens
    from lensmount.optics.paraxial import paraxial

    epd = float(paraxial(load_lens(ROOT / "examples" / "double-gauss-360" / "lens.toml")).epd)
    bore = 0.8 * epd / 2
    tube = Pos(0, 0, -50.0) * (Cylinder(bore + 5.0, 40.0) - Cylinder(bore, 40.0))  # z -70 … -30
    entry = '[parts.hood]\nstep = "housing.step"\n'
    design = make_design(tmp_path / "d", entry, [("tube", tube, {}, {}, {})], scenes=False)
    mount = design / "mount.toml"
    mount.write_text(mount.read_text().replace("count = 3 ", "count = 0 "))  # no vanes where the tube stands
    res = CliRunner().invoke(app, ["regenerate", str(design), "--quiet"])
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert "field 'parts.hood'" in text and "cuts into the beam envelope by " in text and "by -" not in text
    lost = {float(f): float(v) for f, v in re.findall(r"field ([0-9.]+)°: ([0-9.]+) %", text)}
    assert set(lost) == {0.0, 3.5, 5.0}, text
    assert lost[0.0] / 100 == pytest.approx(1 - 0.8 ** 2, abs=0.03), text
    assert lost[3.5] > 5 and lost[5.0] > 5, text  # less: the lens itself trims the off-axis beams

    mount.write_text(mount.read_text().replace(entry, entry + "allow_vignetting = true\n"))
    res = CliRunner().invoke(app, ["regenerate", str(design)])
    assert res.exit_code == 0, res.output
    manifest = json.loads((design / "build" / "manifest.json").read_text())
    assert not any("vignetting field 0°:" in n for n in manifest["notes"])  # a warning, not a note among notes
    [warning] = manifest["warnings"]
    assert warning.startswith("hood: cuts into the beam envelope by ") and "vignetting field 0°:" in warning
    assert "allow_vignetting = true" in warning and f"warning: {warning}" in res.output


def test_vignetting_follows_the_part_not_the_envelope(reference_layout):
    """A screen across half the beam at the image side cuts about half of every field's rays."""
    from build123d import Box, Pos

    from lensmount.cad.step_beam import beam_report, vignetting
    from lensmount.cad.tessellate import tessellate_part

    layout, _ = reference_layout
    zi = layout.prescription.image_z
    half = Pos(100.0, 0, zi - 20.0) * Box(200.0, 400.0, 1.0)  # x > 0 blocked, 20 mm before the image
    mesh = tessellate_part(half, "screen", "baffle", "absorber", [("mount", -1)] * 6, 0.05, 6.0)
    fields, mean, worst, azimuth = vignetting(layout, mesh)
    assert list(fields) == [0.0, 3.5, 5.0]
    assert np.allclose(mean, 0.5, atol=0.03)  # averaged over opposite azimuths: half the pupil, any field
    assert worst[0] == pytest.approx(mean[0], abs=0.03)  # on axis every azimuth loses half
    assert np.all(worst[1:] > mean[1:] + 0.1)  # off axis the beam stands beside the axis: more at one azimuth
    # the most where the image point lies on the screen's side, +x (azimuth 0°), and the report says so
    assert np.all(np.minimum(azimuth[1:], 360.0 - azimuth[1:]) < 5.0), azimuth
    said = beam_report(layout, mesh).lines("°")
    assert re.search(r"field 5°: [0-9.]+ % \(up to 100\.00 % at azimuth 0°\)", said), said


def test_an_open_shell_is_refused_naming_where(tmp_path):
    from build123d import Cylinder, Shell

    from lensmount.cad.step_parts import read_step

    tube = Cylinder(30.0, 50.0) - Cylinder(25.0, 50.0)
    walls = Shell([f for f in tube.faces() if f.center().Z < 24.0])  # the top face left out
    path = write_step(tmp_path / "open.step", [("open-tube", walls, {}, {}, {})])
    with pytest.raises(InputError) as err:
        read_step(path, "housing")
    text = str(err.value)
    assert str(path) in text and "parts.housing.step" in text and "open" in text
    # the free edges are the top's circles: at z = 25 on a radius of 25 or 30 mm
    points = [tuple(map(float, m)) for m in re.findall(r"\((-?[0-9.]+), (-?[0-9.]+), (-?[0-9.]+)\) mm", text)]
    assert points and all(abs(z - 25.0) < 1e-6 and min(abs(math.hypot(x, y) - 25), abs(math.hypot(x, y) - 30))
                          < 1e-6 for x, y, z in points)


def test_a_truncated_step_file_is_one_paragraph_with_what_the_reader_said(tmp_path, capfd):
    """The kernel's own messages (C++ writing to file descriptor 2) do not reach the terminal beside
    the paragraph; the line it stumbled on is folded into it."""
    from build123d import Cylinder

    from lensmount.cad.step_parts import read_step

    path = write_step(tmp_path / "ring.stp", [("ring", Cylinder(30.0, 5.0) - Cylinder(25.0, 5.0), {}, {}, {})])
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    capfd.readouterr()  # what the writer printed
    with pytest.raises(InputError) as err:
        read_step(path, "hood")
    printed = capfd.readouterr()
    assert printed.out == "" and printed.err == ""
    paragraph = str(err.value)
    assert "\n" not in paragraph and "not a readable STEP file" in paragraph and "parts.hood.step" in paragraph
    assert re.search(r"the STEP reader says: .*Line [0-9]+", paragraph), paragraph

    # through regenerate: the mount.toml line of the field that names the file, the file beside it
    design = make_design(tmp_path / "d", '[parts.hood]\nstep = "ring.stp"\n', [("ring", _box(), {}, {}, {})],
                         scenes=False)
    shutil.copy2(path, design / "ring.stp")
    line = (design / "mount.toml").read_text().splitlines().index('step = "ring.stp"') + 1
    capfd.readouterr()
    res = CliRunner().invoke(app, ["regenerate", str(design), "--quiet"])
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert f"mount.toml, line {line}, field 'parts.hood.step' ({design / 'ring.stp'}): not a readable STEP file" in text
    assert capfd.readouterr().err == ""


def test_a_file_in_inches_is_placed_at_its_size_in_mm(tmp_path, reference_layout):
    from build123d import Cylinder

    from lensmount.cad.assembly import step_built_parts
    from lensmount.design.mount import parse_mount

    tube = Cylinder(60.0, 40.0) - Cylinder(55.0, 40.0)  # mm in memory; written in inches
    path = write_step(tmp_path / "tube-inch.step", [("tube", tube, {}, {}, {})], unit="INCH")
    text = path.read_text()
    assert "'INCH'" in text
    num = r"\s*([-0-9.E+]+)\s*"
    points = re.findall(rf"CARTESIAN_POINT\('[^']*',\({num},{num},{num}\)", text)  # 3-D points only
    assert max(math.hypot(float(x), float(y)) for x, y, _ in points) == pytest.approx(60.0 / 25.4, rel=1e-9)
    layout, spec = reference_layout
    zi = layout.prescription.image_z
    entry = {"step": "tube-inch.step", "unit": "inch", "datum": "image-plane", "offset_mm": [0, 0, 30.0],
             "kind": "baffle", "allow_vignetting": True}
    spec = parse_mount({**spec.model_dump(exclude={"parts"}), "parts": {"camera": entry}})
    [part] = step_built_parts(layout, spec, {"camera": path}, {}, set())
    box = part.solid.bounding_box()
    assert box.max.X == pytest.approx(60.0, rel=1e-6) and box.size.Z == pytest.approx(40.0, rel=1e-6)
    assert box.min.Z == pytest.approx(zi + 30.0 - 20.0, abs=1e-6)
    assert part.solid.volume == pytest.approx(math.pi * (60**2 - 55**2) * 40, rel=1e-6)
    wrong = parse_mount({**spec.model_dump(exclude={"parts"}), "parts": {"camera": {**entry, "unit": "mm"}}})
    with pytest.raises(InputError) as err:
        step_built_parts(layout, wrong, {"camera": path}, {}, set())
    assert "parts.camera.unit" in str(err.value) and "inch" in str(err.value) and str(path) in str(err.value)


def test_an_assembly_comes_in_as_parts_keeping_their_names(tmp_path, reference_layout):
    from build123d import Cylinder, Pos

    from lensmount.cad.assembly import step_built_parts
    from lensmount.design.mount import parse_mount

    layout, spec = reference_layout
    body = Cylinder(80.0, 20.0) - Cylinder(70.0, 20.0)
    cap = Pos(0, 0, 30.0) * Cylinder(80.0, 4.0)
    path = write_step(tmp_path / "camera.step", [("body", body, {}, {0: DARK}, {}), ("cap", cap, {}, {}, {2: "OUTER"})])
    entry = {"step": "camera.step", "datum": "image-plane", "offset_mm": [0, 0, 40.0], "allow_vignetting": True,
             "colours": {DARK: "absorber"}, "layers": {"OUTER": "ground-glass"},
             "rules": [{"finish": "mirror", "part": "cap", "normal": [0, 0, -1]}]}
    spec = parse_mount({**spec.model_dump(exclude={"parts"}), "parts": {"camera": entry}})
    parts = {p.name: p for p in step_built_parts(layout, spec, {"camera": path}, {}, set())}
    assert set(parts) == {"body", "cap"}
    assert parts["body"].face_finishes[0] == "absorber" and set(parts["body"].face_finishes[1:]) == {"black-anodised"}
    cap_faces = parts["cap"].solid.faces()
    for k, f in enumerate(cap_faces):
        n = f.normal_at(0.5, 0.5)
        expected = "ground-glass" if k == 2 else ("mirror" if n.Z < -0.99 else "black-anodised")
        assert parts["cap"].face_finishes[k] == expected
    green = {**entry, "colours": {"#00ff00": "absorber"}}
    unknown = parse_mount({**spec.model_dump(exclude={"parts"}), "parts": {"camera": green}})
    with pytest.raises(InputError, match=r"parts\.camera\.colours\.#00ff00.*#1a1a1a"):
        step_built_parts(layout, unknown, {"camera": path}, {}, set())


def test_a_step_part_that_cuts_a_generated_part_is_refused(tmp_path, reference_layout):
    from build123d import Cylinder, Pos

    from lensmount.cad.assembly import build_parts, check_user_parts, step_built_parts
    from lensmount.design.mount import parse_mount

    layout, spec = reference_layout
    barrel = layout.part("barrel").template
    z_back = max(z for _, z in barrel.bore)
    ring = Pos(0, 0, z_back) * (Cylinder(barrel.outer_radius + 5, 6.0) - Cylinder(barrel.outer_radius - 1.0, 6.0))
    path = write_step(tmp_path / "ring.step", [("ring", ring, {}, {}, {})])
    spec = parse_mount({**spec.model_dump(exclude={"parts"}),
                        "parts": {"collar": {"step": "ring.step", "kind": "housing"}}})
    generated = [p for p in build_parts(layout, spec) if p.name in ("barrel", "lens-6")]
    with pytest.raises(GeometryError, match=r"collar and barrel overlap by"):
        check_user_parts(step_built_parts(layout, spec, {"collar": path}, {}, set()) + generated)


def test_a_step_hood_that_collides_with_the_hoods_vanes_says_what_to_set(tmp_path, reference_layout):
    """The generated vanes stand in the generated hood; a user's hood with a narrower bore meets them,
    and the error says which mount.toml setting leaves them out (the reference places its hood vanes
    evenly: `count`)."""
    from build123d import Cylinder, Pos

    from lensmount.cad.assembly import build_assembly
    from lensmount.design.mount import parse_mount

    layout, spec = reference_layout
    hood = layout.part("hood").template
    ri, z0, z1 = hood.inner_radius, hood.z_front, hood.z_back - 3.0
    assert {p.template.outer_radius for p in layout.parts if p.kind == "vane" and p.template.z_front < z1} == {ri}
    tube = Pos(0, 0, 0.5 * (z0 + z1)) * (Cylinder(ri + 2.0, z1 - z0) - Cylinder(ri - 0.5, z1 - z0))
    path = write_step(tmp_path / "hood.step", [("hood", tube, {}, {}, {})])
    spec = parse_mount({**spec.model_dump(exclude={"parts"}),
                        "parts": {"hood": {"step": "hood.step", "offset_mm": [0, 0, -layout.prescription.vertex_z[0]]}}})
    with pytest.raises(GeometryError) as err:
        build_assembly(layout.prescription, spec, None, None, {"hood": path})
    text = str(err.value)
    assert re.search(r"hood and vane-[0-9] overlap by", text), text
    assert "[vanes] count = 0 (no vanes in the hood) in mount.toml" in text
    vanes = {k: v for k, v in spec.vanes.model_dump().items() if k != "count"} | {"placement": "line-of-sight"}
    line_of_sight = parse_mount({**spec.model_dump(), "vanes": vanes})
    with pytest.raises(GeometryError, match=r"\[vanes\] positions_mm = \[\] \(no vanes in the hood\)"):
        build_assembly(layout.prescription, line_of_sight, None, None, {"hood": path})


@pytest.mark.parametrize("steps", [3, 30])
def test_face_numbers_on_a_round_part_do_not_overlap(steps):
    """A stepped ring: every annulus and cylinder has its highest point on the same vertical line, where
    the numbers used to pile up. Each number's box stands apart from every other's in both views."""
    import itertools

    import matplotlib.pyplot as plt
    from build123d import Cylinder, Pos
    from matplotlib.text import Text

    from lensmount.cad.step_parts import face_figure
    from lensmount.cad.tessellate import tessellate_part

    ring = Cylinder(30.0, 2.0)
    for k in range(1, steps):
        ring = ring + Pos(0, 0, 2.0 * k) * Cylinder(30.0 - 0.5 * k, 2.0)
    ring = ring - Cylinder(10.0, 4.0 * steps)
    n = len(ring.faces())
    mesh = tessellate_part(ring, "ring", "hood", "absorber", [("mount", -1)] * n, 0.05, 6.0)
    fig = face_figure(mesh, "ring")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        boxes = [Text.get_window_extent(t, renderer) for t in ax.texts]  # the number's box, not its leader
        assert sorted(int(t.get_text()) for t in ax.texts) == list(range(n))
        assert not [(a, b) for a, b in itertools.combinations(boxes, 2) if a.overlaps(b)]
    plt.close(fig)


def test_a_sliver_to_the_glass_is_found():
    from build123d import Box, Pos

    from lensmount.cad.step_parts import sliver_to_glass

    glass = Box(10, 10, 10)
    assert sliver_to_glass(Pos(10.003, 0, 0) * Box(10, 10, 10), [("lens-1", glass)], 0.01)[1] == pytest.approx(0.003)
    assert sliver_to_glass(Pos(10.0, 0, 0) * Box(10, 10, 10), [("lens-1", glass)], 0.01) is None  # touching
    assert sliver_to_glass(Pos(10.02, 0, 0) * Box(10, 10, 10), [("lens-1", glass)], 0.01) is None  # clear


def test_mount_entry_errors_name_file_and_field(tmp_path):
    from lensmount.design.folder import load_design

    design = make_design(tmp_path / "d", '[parts.housing]\nstep = "missing.step"\n', [("x", _box(), {}, {}, {})],
                         scenes=False)
    with pytest.raises(InputError, match=r"mount\.toml.*field 'parts\.housing\.step'.*missing\.step"):
        load_design(design)
    (design / "mount.toml").write_text((design / "mount.toml").read_text().replace(
        'step = "missing.step"', 'step = "housing.step"\ncolour = "#000000"'))
    with pytest.raises(InputError, match=r"parts\.housing\.colour"):
        load_design(design)


def test_the_step_file_is_part_of_the_design(tmp_path):
    from lensmount.design.folder import load_design
    from lensmount.loop.provenance import design_changes, design_record

    design = make_design(tmp_path / "d", '[parts.housing]\nstep = "housing.step"\n', [("x", _box(), {}, {}, {})])
    before = load_design(design)
    record = design_record(before)
    write_step(design / "housing.step", [("x", _box(11.0), {}, {}, {})])  # a new export
    after = load_design(design)
    assert before.input_hash != after.input_hash
    assert design_changes(record, design_record(after)) == ["file housing.step: changed"]
    assert design_changes(record, record) == []


def _box(size: float = 10.0):
    from build123d import Box

    return Box(size, size, size)


UC2 = ROOT / "tests" / "cad" / "data" / "uc2" / "20_Cube_Insert_Thorlabs.stp"
UC2_HOOD = '''
[parts.hood]
step = "20_Cube_Insert_Thorlabs.stp"
unit = "mm"
datum = "surface-1"
rotate_deg = [180.0, 0.0, 0.0]
offset_mm = [20.9299280222158, 20.9299280222158, 8.0]
colours = { "#bfbfbf" = "black-anodised" }
'''


def test_the_public_step_file_reads_as_one_valid_closed_solid():
    import cadquery as cq

    from lensmount.cad.step_parts import free_edges, read_step

    step = read_step(UC2, "hood")
    assert step.unit == "mm" and [s.name for s in step.solids] == ["20_Cube_Insert_Thorlabs"]
    solid = step.solids[0]
    assert len(solid.face_names) == 34 and set(solid.face_colours) == {"#bfbfbf"}
    assert solid.solid.is_valid and not free_edges(solid.solid.wrapped)
    other = cq.importers.importStep(str(UC2)).val()  # CadQuery's reader, for the volume
    assert solid.solid.volume == pytest.approx(other.Volume(), rel=1e-9)
    box = solid.solid.bounding_box()  # the 3 mm plate at z 10…13 and its pins to z 22.24 (the file's frame)
    assert (box.min.Z, box.max.Z) == (pytest.approx(10.0, abs=1e-9), pytest.approx(22.2358797913631, abs=1e-9))


@pytest.mark.slow
def test_a_public_step_file_as_the_cooke_triplets_hood(tmp_path):
    """The UC2 Thorlabs insert (tests/cad/data/uc2/SOURCES.md) as the Cooke triplet's hood:
    valid, its clearance to the beam reported, `check` and case 2 run."""
    runner = CliRunner()
    design = tmp_path / "cooke"
    assert runner.invoke(app, ["init", str(design), "--example", "cooke-triplet"]).exit_code == 0
    shutil.copy2(UC2, design / UC2.name)
    mount = design / "mount.toml"
    # no vanes: there is no generated hood to hold them
    mount.write_text(mount.read_text().replace("count = 2\n", "count = 0\n") + UC2_HOOD)
    res = runner.invoke(app, ["regenerate", str(design)])
    assert res.exit_code == 0, res.output
    manifest = json.loads((design / "build" / "manifest.json").read_text())
    notes = " ".join(manifest["notes"])
    assert "hood: from 20_Cube_Insert_Thorlabs.stp (mm), 34 faces: 34 black-anodised (by colour)" in notes
    clearance = float(re.search(r"hood: clears the beam envelope by ([0-9.]+) mm", notes).group(1))
    assert clearance > 0.1  # the vane margin of this mount
    assert re.findall(r"field [0-9.]+°: ([0-9.]+) %", notes) == ["0.00"] * 3
    res = runner.invoke(app, ["check", str(design)])
    assert res.exit_code in (0, 1), res.output  # 1: lit walls seen (the barrel's, as without the part)
    assert (design / "build" / "check" / "check.json").is_file()
    doc = tomllib_loads((design / "scenes" / "case2-lambertian.toml").read_text())
    doc["detector"]["pixels"] = [40, 40]
    (design / "scenes" / "case2-tiny.toml").write_text(tomli_dumps(doc))
    out = tmp_path / "run"
    res = runner.invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / "case2-tiny.toml"),
                              "--photons-per-pass", "5000", "--passes", "2", "--workers", "1", "--out", str(out),
                              "--no-record"])
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    assert math.isfinite(summary["stray_fraction"]) and summary["stray_fraction"] > 0


@pytest.mark.slow
def test_the_step_housing_agrees_with_the_generated_one(step_housing, tmp_path):
    """Case 2 (sun 7°) on the reference with its generated housing and with the same housing read
    from STEP: the stray fractions agree within the combined error. Both designs keep the example's
    own treatment, whose "*" rule paints every generated face black-paint; the STEP faces keep the
    finishes their colours give them, which `finish:` rules re-map to black-paint, so the two differ
    in where the housing's solid came from and nothing else; case 2 scatters at every black-paint face."""
    step_design = Path(shutil.copytree(step_housing[0], tmp_path / "step"))  # the module's design stays as it is
    generated = make_design(tmp_path / "generated", "")
    results = {}
    for name, design in (("generated", generated), ("step", step_design)):
        shutil.copy2(ROOT / "examples" / "double-gauss-360" / "finishes.toml", design / "finishes.toml")
        if name == "step":
            with open(design / "finishes.toml", "a") as f:
                f.write("".join(f'"finish:{n}" = "black-paint"\n' for n in ("absorber", "black-anodised", "ground-glass")))
        doc = tomllib_loads((design / "scenes" / "case2-lambertian.toml").read_text())
        doc["detector"]["pixels"] = [60, 60]  # the stray fraction is what is compared: a coarse view map reads it
        (design / "scenes" / "case2-check.toml").write_text(tomli_dumps(doc))
        res = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / "case2-check.toml"),
                                       "--photons-per-pass", "20000", "--passes", "8", "--workers", "1",
                                       "--out", str(tmp_path / name), "--no-record"])
        assert res.exit_code == 0, res.output
        results[name] = json.loads((tmp_path / name / "summary.json").read_text())
    a, b = results["generated"], results["step"]
    assert a["stray_fraction"] > 0 and b["stray_fraction"] > 0
    combined = math.hypot(a["stray_fraction_std_error"], b["stray_fraction_std_error"])
    assert abs(a["stray_fraction"] - b["stray_fraction"]) <= 3 * combined


@pytest.mark.slow
def test_compare_between_revisions_that_differ_only_in_the_step_file(step_housing, tmp_path):
    """A new export of the housing (its back painted another colour, the same shape): compare
    names the file that changed and gives its verdict."""
    from lensmount.cad.layout import plan
    from lensmount.design.lens import load_lens
    from lensmount.design.mount import load_mount

    design = tmp_path / "design"
    shutil.copytree(step_housing[0], design)  # the module's design stays as it is
    doc = tomllib_loads((design / "scenes" / "case2-lambertian.toml").read_text())
    doc["detector"]["pixels"] = [60, 60]
    doc["effects"]["scatter"] = True  # every face the design's finishes let scatter (its STEP faces too)
    (design / "scenes" / "case2-rev.toml").write_text(tomli_dumps(doc))
    runner = CliRunner()

    def run(out):
        res = runner.invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / "case2-rev.toml"),
                                  "--photons-per-pass", "5000", "--passes", "4", "--workers", "1", "--out", str(out),
                                  "--no-record"])
        assert res.exit_code == 0, res.output

    run(tmp_path / "rev-a")
    ex = ROOT / "examples" / "double-gauss-360"
    layout = plan(load_lens(ex / "lens.toml"), load_mount(ex / "mount.toml"))
    housing = layout.part("housing").template.build()
    names, colours = face_plan(housing, layout.prescription.image_z)
    colours = {k: (DARK if names[k] == "back" else c) for k, c in colours.items()}  # the new export
    write_step(design / "housing.step", [("mechanical-housing", housing, names, colours, {})])
    run(tmp_path / "rev-b")
    res = runner.invoke(app, ["compare", str(tmp_path / "rev-a"), str(tmp_path / "rev-b")])
    assert res.exit_code in (0, 1), res.output
    assert "file housing.step: changed" in res.output
    verdict = json.loads((tmp_path / "rev-b" / "compare" / "compare.json").read_text())
    assert "file housing.step: changed" in verdict["design_changes"] and "verdict" in verdict


def tomllib_loads(text: str) -> dict:
    import tomllib

    return tomllib.loads(text)


def tomli_dumps(doc: dict) -> str:
    import tomli_w

    return tomli_w.dumps(doc)


def test_a_step_part_whose_datum_moves_is_another_part(tmp_path, reference_layout):
    """A STEP part is placed at its datum (here the image plane): a lens edit that moves the datum moves
    the part with its `[parts.NAME]` entry unchanged, so its hash (what regenerate's kept STEP file and
    the tessellation a long-lived process keeps, `cad.assembly._part_mesh`, are keyed by) changes too."""
    from dataclasses import replace

    from build123d import Cylinder

    from lensmount.cad.assembly import step_built_parts
    from lensmount.design.mount import parse_mount

    layout, spec = reference_layout
    path = write_step(tmp_path / "tube.step", [("tube", Cylinder(60.0, 40.0) - Cylinder(55.0, 40.0), {}, {}, {})])
    entry = {"step": "tube.step", "datum": "image-plane", "offset_mm": [0, 0, 30.0], "kind": "baffle",
             "allow_vignetting": True}
    spec = parse_mount({**spec.model_dump(exclude={"parts"}), "parts": {"camera": entry}})
    p = layout.prescription
    last = p.surfaces[-1]
    longer = replace(p, surfaces=p.surfaces[:-1] + (replace(last, thickness=last.thickness + 1.0),))
    assert longer.image_z == pytest.approx(p.image_z + 1.0)
    [here] = step_built_parts(replace(layout, notes=[]), spec, {"camera": path}, {}, set())
    [moved] = step_built_parts(replace(layout, prescription=longer, notes=[]), spec, {"camera": path}, {}, set())
    assert moved.solid.bounding_box().min.Z == pytest.approx(here.solid.bounding_box().min.Z + 1.0, abs=1e-6)
    assert moved.hash != here.hash
