"""`lensmount check`: the geometric stray-light check (lit walls the detector sees) and the
realised entrance pupil, on the reference design's geometry (built once per session)."""

import json

import pytest
from typer.testing import CliRunner

from lensmount.cli import app


def test_sun_just_outside_the_field_lights_walls_the_detector_sees(reference):
    """The reference's field is ±5°: at 5.5° the sun's image lands just beyond the detector on the
    housing bore, which the detector sees, and the rear group's spacers catch light it sees too."""
    design, out, _ = reference
    res = CliRunner().invoke(app, ["check", str(design), "--out", str(out), "--exclusion-deg", "5.5"])
    assert res.exit_code == 1, res.output
    doc = json.loads((out / "check" / "check.json").read_text())
    assert not doc["passed"]
    walls = {(w["part"], w["face"]) for w in doc["lit_walls_seen"]}
    assert ("housing", 0) in walls
    assert "housing face 0" in res.output
    assert (out / "check" / "check.png").stat().st_size > 10_000
    pupil = doc["entrance_pupil"]
    assert abs(pupil["realised_mm"] / pupil["design_mm"] - 1) < 5e-3 and pupil["limited_by"] == ["diaphragm"]
    assert "f/7.00" in res.output


def test_sun_far_outside_the_field_lights_nothing_the_detector_sees(reference):
    design, out, _ = reference
    res = CliRunner().invoke(app, ["check", str(design), "--out", str(out), "--exclusion-deg", "30"])
    assert res.exit_code == 0, res.output
    assert "no lit wall is seen" in res.output


def test_bad_exclusion_angle_is_an_input_error(reference):
    design, out, _ = reference
    res = CliRunner().invoke(app, ["check", str(design), "--out", str(out), "--exclusion-deg", "95"])
    assert res.exit_code == 2 and "--exclusion-deg" in res.output and "Traceback" not in res.output


@pytest.mark.slow
def test_hood_without_vanes_sun_just_outside_the_field(tmp_path, design_copier):
    """A deliberately bad design: the reference hood without vanes, the sun at 5.5°. Vanes cannot
    change what the detector sees through the lens (the hood lies outside the field's beam), so the
    lit walls found are the ones inside: the check must exit 1 and name the part and face."""
    d = design_copier("double-gauss-360", tmp_path / "d")
    text = (d / "mount.toml").read_text().replace("count = 3", "count = 0").replace("in_air_gaps = 1", "in_air_gaps = 0")
    (d / "mount.toml").write_text(text + "\n")
    res = CliRunner().invoke(app, ["regenerate", str(d), "--quiet", "--check"])
    assert res.exit_code == 0 or res.exit_code == 1, res.output
    res = CliRunner().invoke(app, ["check", str(d), "--exclusion-deg", "5.5"])
    assert res.exit_code == 1
    assert "housing face 0" in res.output


def test_unknown_view_is_an_input_error(tmp_path, design_copier):
    d = design_copier("double-gauss-360", tmp_path / "d")
    res = CliRunner().invoke(app, ["check", str(d), "--from", "moon"])
    assert res.exit_code == 2 and "--from" in res.output and "aperture" in res.output
    assert "Traceback" not in res.output and not (d / "build").exists()  # refused before the build


def test_the_two_views_write_separate_files(reference):
    """`check --from aperture` writes check-aperture.png/.json and leaves the detector view's check.json as it was."""
    design, out, _ = reference
    res = CliRunner().invoke(app, ["check", str(design), "--out", str(out), "--exclusion-deg", "30"])
    assert res.exit_code == 0, res.output
    before = (out / "check" / "check.json").read_text()
    res = CliRunner().invoke(app, ["check", str(design), "--out", str(out), "--exclusion-deg", "30",
                                   "--from", "aperture"])
    assert res.exit_code in (0, 1), res.output
    assert "check-aperture.png" in res.output
    assert json.loads((out / "check" / "check-aperture.json").read_text())["seen_from"] == "aperture"
    assert (out / "check" / "check-aperture.png").stat().st_size > 10_000
    assert (out / "check" / "check.json").read_text() == before  # the detector's view is untouched


def test_a_pupil_no_axial_ray_passes_is_explained_not_divided_by(reference, tmp_path):
    """A glass face tagged as metal (a `mount` face across the beam) stops every on-axis ray: the
    realised pupil is 0, and check says so and names the part, with no f-number of 1/0 (no traceback,
    nothing infinite or NaN in check.json)."""
    import math
    import shutil

    from lensmount.cli.check import run_check
    from lensmount.mesh import FaceTag, TaggedMesh

    design, out, _ = reference
    folder = tmp_path / "build"
    shutil.copytree(out, folder, ignore=shutil.ignore_patterns(".cache"))
    mesh = TaggedMesh.load(folder / "mesh.npz")
    table = [FaceTag(t.part, t.kind, "mount", t.finish, -1, t.face, t.label)
             if (t.part, t.role, t.surface) == ("lens-1", "optical", 0) else t for t in mesh.tag_table]
    TaggedMesh(mesh.vertices, mesh.triangles, mesh.tags, table).save(folder / "mesh.npz")
    said: list[str] = []
    run_check(design, folder, 30.0, echo=said.append)
    line = next(s for s in said if s.startswith("entrance pupil"))
    assert "none realised" in line and "lens-1" in line and "f/inf" not in line, line
    pupil = json.loads((folder / "check" / "check.json").read_text())["entrance_pupil"]
    assert pupil["realised_mm"] == 0.0 and pupil["realised_f_number"] is None and pupil["limited_by"] == ["lens-1"]
    assert all(math.isfinite(v) for v in (pupil["design_mm"], pupil["design_f_number"]))


def test_a_finite_object_lights_the_mount_from_its_object_plane():
    """For a lens whose object is at a finite distance the check's light leaves the object plane: from the
    point seen at the angle from the paraxial entrance pupil (as the file's field angles are) toward the
    whole front opening; at infinity it is parallel, at that angle."""
    import math
    from dataclasses import replace

    import numpy as np

    from lensmount.design.lens import load_lens
    from lensmount.loop.sightlines import _lit_rays
    from lensmount.optics.paraxial import paraxial
    from lensmount.scene.scene import FrontOpening
    from tests.cad.test_finite_conjugates import SMALL_FINITE

    p = load_lens(SMALL_FINITE)
    opening = FrontOpening(-12.0, 9.0)
    u = np.linspace(-0.7, 0.7, 5)
    su, sv = (g.ravel() for g in np.meshgrid(u, u))
    o, d = _lit_rays(p, opening, 100.0, 20.0, 90.0, su, sv)
    assert np.allclose(o[:, 2], -p.object_distance) and np.allclose(o[:, 0], 0.0) and np.all(o[:, 1] > 0)
    assert math.degrees(math.atan(o[0, 1] / (p.object_distance + paraxial(p).entrance_pupil_z))) == pytest.approx(20.0)
    at = o + d * ((opening.z - o[:, 2]) / d[:, 2])[:, None]     # where each ray crosses the opening's plane
    assert np.allclose(at[:, :2], np.column_stack([su, sv]) * (opening.radius * 1.02 + 1e-3))
    o, d = _lit_rays(replace(p, object_distance=math.inf), opening, 100.0, 20.0, 90.0, su, sv)
    assert np.allclose(d, [0.0, -math.sin(math.radians(20.0)), math.cos(math.radians(20.0))])
