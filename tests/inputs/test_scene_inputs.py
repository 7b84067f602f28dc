"""Scene and mount values that used to be ignored or defaulted without a word (found by
grepping the design and scene layers): each is now an InputError naming field and line."""

from __future__ import annotations

import shutil
from dataclasses import replace

import pytest

from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.design.scene import load_scene, scene_from_dict
from lensmount.errors import InputError
from lensmount.scene import primitives
from lensmount.scene.build import build_scene
from tests.inputs.conftest import EXAMPLES
from tests.trace.geometry import air_plane, scene_dict


def _mount_parts() -> TaggedMesh:
    """A barrel and a diaphragm-edge ring, tagged as the CAD layer tags (no CAD kernel)."""
    barrel = primitives.tube(0.0, 50.0, 12.0, 14.0, part="barrel", kind="barrel", finish="black-anodised")
    edge = primitives.tube(20.0, 20.05, 5.0, 12.0, part="diaphragm", kind="diaphragm", finish="black-anodised")
    edge = TaggedMesh(edge.vertices, edge.triangles, edge.tags,
                      [FaceTag("diaphragm", "diaphragm", "diaphragm-edge", "black-anodised")])
    return TaggedMesh.concatenate([barrel, edge])


def _write(tmp_path, data):
    """DESIGN/scenes/scene.toml with the test condition, DESIGN/finishes.toml with the treatment
    tables of `data`; the scene file's path."""
    import tomli_w

    design = tmp_path / "design"
    (design / "scenes").mkdir(parents=True, exist_ok=True)
    treatment = {k: data.pop(k) for k in ("finishes", "coatings", "assign") if k in data}
    (design / "finishes.toml").write_text(tomli_w.dumps(treatment))
    path = design / "scenes" / "scene.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def _load(path):
    """The scene file with its design's finishes, as simulate reads it."""
    from lensmount.design.finishes import load_finishes

    return load_scene(path, load_finishes(path.parent.parent))


def test_selector_that_matches_nothing_names_its_line_in_build_scene(tmp_path):
    path = _write(tmp_path, scene_dict(assign={"*": "absorber", "role:diafragm-edge": "ground-glass"}))
    spec = _load(path)
    with pytest.raises(InputError) as err:
        build_scene(air_plane(), _mount_parts(), spec)
    e = err.value
    finishes = path.parent.parent / "finishes.toml"
    line = finishes.read_text().splitlines().index('"role:diafragm-edge" = "ground-glass"') + 1
    assert e.file == str(finishes) and e.line == line and e.field == "assign.role:diafragm-edge"
    assert "did you mean 'role:diaphragm-edge'" in e.detail
    assert e.valid.startswith("part: barrel, diaphragm; role: diaphragm-edge, mount; kind: barrel, diaphragm; "
                              "finish: black-anodised")
    # The right spelling builds, and the edge gets the finish.
    spec = scene_from_dict(scene_dict(assign={"*": "absorber", "role:diaphragm-edge": "ground-glass"}))
    scene = build_scene(air_plane(), _mount_parts(), spec)
    assert scene.finish_of_tag == ["absorber", "ground-glass"]


def test_undefined_mount_finish_without_a_rule_is_an_error_not_an_absorber():
    mesh = _mount_parts()
    mesh = TaggedMesh(mesh.vertices, mesh.triangles, mesh.tags,
                      [FaceTag("barrel", "barrel", "mount", "black-anodized"), mesh.tag_table[1]])
    spec = scene_from_dict(scene_dict(assign={"role:diaphragm-edge": "ground-glass"}))
    with pytest.raises(InputError) as err:
        build_scene(air_plane(), mesh, spec)
    assert "'black-anodized'" in err.value.detail and "barrel" in err.value.detail
    assert "black-anodised" in err.value.valid


def test_coating_for_a_surface_the_lens_does_not_have(tmp_path):
    path = _write(tmp_path, scene_dict(coatings={"default": "perfect-ar", "surface-7": "uncoated"}))
    with pytest.raises(InputError) as err:
        build_scene(air_plane(), _mount_parts(), _load(path))
    assert err.value.field == "coatings.surface-7" and err.value.line is not None and "surface-1" in err.value.valid
    assert err.value.file == str(path.parent.parent / "finishes.toml")


@pytest.mark.parametrize("patch,field,words", [
    ({"source": {"type": "collimated", "off_axis_deg": 5.0, "angular_diameter_deg": 0.53}},
     "source.angular_diameter_deg", "angular_diameter_deg applies to type = 'sun' only"),
    ({"objects": [{"type": "rectangle", "name": "r", "width_mm": 5.0, "height_mm": 5.0, "radius_mm": 3.0}]},
     "objects.0", "takes width_mm, height_mm, not radius_mm"),
    ({"source": {"type": "point", "off_axis_deg": 5.0}}, "source.off_axis_deg",
     "off_axis_deg applies to type = 'sun' or 'collimated' only"),
    ({"source": {"type": "sun", "off_axis_deg": 5.0, "height_mm": 3.0}}, "source.height_mm",
     "height_mm applies to type = 'point' or 'disc' only"),
    ({"source": {"type": "point", "radius_mm": 2.0}}, "source.radius_mm", "radius_mm applies to type = 'disc' only"),
    ({"source": {"type": "disc"}}, "source.radius_mm", "missing key 'radius_mm'"),
    ({"source": {"type": "sun"}}, "source.off_axis_deg", "missing key 'off_axis_deg'"),
    ({"source": {"type": "laser", "off_axis_deg": 5.0}}, "source.type", "unknown source type 'laser'"),
])
def test_values_that_would_be_ignored(tmp_path, patch, field, words):
    path = _write(tmp_path, scene_dict(**patch))
    with pytest.raises(InputError) as err:
        _load(path)
    assert err.value.field == field and words in err.value.detail and err.value.line is not None


def test_a_collimated_source_without_sun_keys_is_fine():
    scene_from_dict(scene_dict(source={"type": "collimated", "off_axis_deg": 5.0}))


def test_a_point_source_needs_a_finite_object_or_a_plane(tmp_path):
    path = _write(tmp_path, scene_dict(source={"type": "point", "height_mm": 2.0}))
    with pytest.raises(InputError) as err:
        build_scene(air_plane(), _mount_parts(), _load(path))  # the lens's object is at infinity
    assert err.value.field == "source.z_mm" and "object at infinity" in err.value.detail
    assert err.value.file == str(path) and err.value.line is not None
    stopped = air_plane().with_surfaces([replace(air_plane().surfaces[0], is_stop=True, radius=100.0)])
    scene = build_scene(stopped, _mount_parts(),
                        scene_from_dict(scene_dict(source={"type": "point", "height_mm": 2.0, "z_mm": -300.0})))
    assert scene.source.centre == pytest.approx((0.0, 2.0, -300.0))  # azimuth 90°: toward +y


def test_mount_element_number_the_lens_does_not_have(tmp_path):
    from lensmount.design.folder import load_design

    d = tmp_path / "d"
    d.mkdir()
    for name in ("lens.toml", "mount.toml"):
        shutil.copy2(EXAMPLES / "cooke-triplet" / name, d / name)
    text = (d / "mount.toml").read_text().replace("semi_diameter_mm = { 1 = 10.2, 2 = 9.8, 3 = 8.0 }",
                                                  "semi_diameter_mm = { 1 = 10.2, 2 = 9.8, 4 = 8.0 }")
    (d / "mount.toml").write_text(text)
    with pytest.raises(InputError) as err:
        load_design(d)
    e = err.value
    assert e.field == "lens_edge.semi_diameter_mm.4" and "no element 4" in e.detail and "1 to 3" in e.valid
    assert e.line == text.splitlines().index(next(x for x in text.splitlines() if "4 = 8.0" in x)) + 1


def test_mount_errors_found_while_planning_the_cad_carry_the_line(tmp_path):
    from lensmount.cad.pipeline import regenerate

    d = tmp_path / "d"
    d.mkdir()
    for name in ("lens.toml", "mount.toml"):
        shutil.copy2(EXAMPLES / "cooke-triplet" / name, d / name)
    text = (d / "mount.toml").read_text().replace('default = "spacer"', 'default = "spacer"\nelement = { 7 = "shoulder" }')
    (d / "mount.toml").write_text(text)
    with pytest.raises(InputError) as err:
        regenerate(d, tmp_path / "out")
    e = err.value
    assert e.file == str(d / "mount.toml") and e.field == "seats.element.7"
    assert e.line == text.splitlines().index('element = { 7 = "shoulder" }') + 1


def test_without_assign_rules_every_face_keeps_its_mount_finish():
    """Omitting [assign] and adding one rule agree on the faces the rule does not name."""
    none = build_scene(air_plane(), _mount_parts(), scene_from_dict(scene_dict(assign={})))
    data = scene_dict()
    del data["assign"]
    omitted = build_scene(air_plane(), _mount_parts(), scene_from_dict(data))
    one = build_scene(air_plane(), _mount_parts(), scene_from_dict(scene_dict(assign={"role:diaphragm-edge": "mirror"})))
    assert none.finish_of_tag == omitted.finish_of_tag == ["black-anodised", "black-anodised"]
    assert one.finish_of_tag == ["black-anodised", "mirror"]


@pytest.mark.parametrize("names", [["barrel"], ["plate", "plate"]])
def test_object_named_like_a_part_would_refinish_it(tmp_path, names):
    objects = [{"type": "disk", "name": n, "centre_mm": [0, 0, -20.0], "radius_mm": 5.0, "finish": "mirror"}
               for n in names]
    path = _write(tmp_path, scene_dict(objects=objects))
    with pytest.raises(InputError) as err:
        build_scene(air_plane(), _mount_parts(), _load(path))
    assert err.value.field == f"objects.{len(names) - 1}.name" and err.value.line is not None
    assert f"'{names[-1]}' is already taken" in err.value.detail


def test_detector_without_a_size_takes_the_housing_size_with_square_pixels(tmp_path):
    """A scene that leaves out [detector] width and height gets the size mount.toml's [housing]
    was built for, and 600 square pixels along the longer side; one of the two alone is an error."""
    from lensmount.loop.prepare import read_inputs

    design = tmp_path / "cooke"
    shutil.copytree(EXAMPLES / "cooke-triplet", design)
    text = (design / "scenes" / "case2-lambertian.toml").read_text()
    text = text.replace("pixels = [360, 240]\n", "")
    scene = design / "scenes" / "no-size.toml"
    scene.write_text(text)
    loaded, spec = read_inputs(design, scene)
    housing = loaded.mount.housing
    assert (spec.detector.width_mm, spec.detector.height_mm) == (housing.detector_width_mm, housing.detector_height_mm)
    nx, ny = spec.detector.pixels
    assert max(nx, ny) == 600
    assert spec.detector.width_mm / nx == pytest.approx(spec.detector.height_mm / ny, rel=2e-3)
    assert spec.source_file == str(scene)  # errors found later still name the file
    # Outside a design folder there is no housing to take the size from.
    with pytest.raises(InputError) as err:
        build_scene(air_plane(), _mount_parts(), load_scene(scene))
    assert err.value.field == "detector.width_mm" and err.value.file == str(scene)

    scene.write_text(text.replace("[detector]\n", "[detector]\nwidth_mm = 30.0\n"))
    with pytest.raises(InputError) as err:
        load_scene(scene)
    assert "detector" in err.value.field and "neither" in str(err.value)
