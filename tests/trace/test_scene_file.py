"""Scene files: the examples load, unknown keys and bad values are InputErrors naming the field."""

from pathlib import Path

import numpy as np
import pytest

from lensmount.errors import InputError
from lensmount.design.scene import load_scene, scene_from_dict
from lensmount.design.finishes import finish_of
from lensmount.mesh import FaceTag
from tests.trace.geometry import double_gauss, double_gauss_mesh, scene_dict
from lensmount.scene.build import build_scene

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


@pytest.mark.parametrize("design", sorted(p.name for p in EXAMPLES.iterdir() if (p / "mount.toml").is_file()))
def test_example_scenes_load_with_their_design_finishes(design):
    """Every example scene is a test condition only; the design's finishes.toml gives the treatment."""
    from lensmount.design.finishes import load_finishes

    finishes = load_finishes(EXAMPLES / design)
    assert finishes.source_file == str(EXAMPLES / design / "finishes.toml")
    scenes = sorted((EXAMPLES / design / "scenes").glob("*.toml"))
    assert scenes
    for path in scenes:
        spec = load_scene(path, finishes)
        assert (spec.finishes, spec.coatings, spec.assign) == (finishes.finishes, finishes.coatings, finishes.assign)
        if design == "double-gauss-360":
            assert spec.source.off_axis_deg == 7.0 and spec.detector.pixels == (600, 600)
            assert spec.coatings["default"] == "perfect-ar"


@pytest.mark.parametrize("patch,field", [
    ({"colour": 1}, "colour"),
    ({"source": {"type": "sun", "off_axis_deg": 7.0, "elevation": 3}}, "source.elevation"),
    ({"source": {"type": "laser", "off_axis_deg": 7.0}}, "source.type"),
    ({"detector": {"width_mm": -1, "height_mm": 1}}, "detector.width_mm"),
    ({"objects": [{"type": "disk", "name": "d"}]}, "objects.0"),
    ({"objects": [{"type": "disk", "name": "d", "radius_mm": 1.0, "finish": "nope"}]}, "objects.0.finish"),
])
def test_bad_scene_files_name_the_field(tmp_path, patch, field):
    import tomli_w

    data = scene_dict(**patch)
    del data["assign"]  # the design's, not the scene's
    path = tmp_path / "bad.toml"
    path.write_text(tomli_w.dumps(data))
    with pytest.raises(InputError) as exc:
        load_scene(path)
    text = exc.value.paragraph()
    assert str(path) in text and field in text, text


@pytest.mark.parametrize("tables,field", [
    ({"coatings": {"default": "shiny"}}, "coatings"),
    ({"coatings": {"surface-0": "uncoated"}}, "coatings"),
    ({"finishes": {"x": {"model": "lambertian", "reflectance": 2.0}}, "assign": {"*": "x"}}, "finishes.x.reflectance"),
    ({"finishes": {"x": {"model": "lambertian", "colour": 1}}, "assign": {"*": "x"}}, "finishes.x"),
    ({"finishes": {"x": {"reflectance": 0.1}}}, "finishes.x.model"),
    ({"assign": {"*": "nope"}}, "assign.*"),
    ({"assign": {"colour:red": "absorber"}}, "assign.colour:red"),
    ({"paint": {}}, "paint"),
])
def test_bad_finishes_files_name_the_field(tmp_path, tables, field):
    import tomli_w

    from lensmount.design.finishes import load_finishes

    path = tmp_path / "finishes.toml"
    path.write_text(tomli_w.dumps(tables))
    with pytest.raises(InputError) as exc:
        load_finishes(tmp_path)
    text = exc.value.paragraph()
    assert str(path) in text and field in text and exc.value.line is not None, text


def test_a_design_without_finishes_toml_keeps_the_mount_finishes():
    """No finishes.toml: the built-in library, no rules (every face its mount finish), perfect-ar."""
    from lensmount.design.finishes import Finishes, load_finishes

    assert load_finishes(ROOT / "tests") == Finishes() and Finishes().assign == {}
    assert Finishes().coatings == {"default": "perfect-ar"}


def test_not_toml_names_the_line(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[source]\noff_axis_deg = = 7\n")
    with pytest.raises(InputError) as exc:
        load_scene(path)
    assert exc.value.line == 2


def test_assignment_priority():
    assign = {"*": "absorber", "kind:barrel": "black-anodised", "role:diaphragm-edge": "ground-glass",
              "part:spacer-2": "mirror", "finish:matt": "ground-glass"}
    lib = {k: {} for k in ("absorber", "black-anodised", "ground-glass", "mirror")}
    tag = FaceTag("spacer-2", "spacer", "diaphragm-edge", "matt")
    assert finish_of(tag, assign, lib) == "mirror"
    assert finish_of(FaceTag("diaphragm", "diaphragm", "diaphragm-edge", "x"), assign, lib) == "ground-glass"
    assert finish_of(FaceTag("barrel", "barrel", "mount", "x"), assign, lib) == "black-anodised"
    assert finish_of(FaceTag("hood", "hood", "mount", "matt"), assign, lib) == "ground-glass"
    assert finish_of(FaceTag("hood", "hood", "mount", "x"), assign, lib) == "absorber"
    assert finish_of(FaceTag("lens-1", "lens", "optical", "x", surface=0), assign, lib) is None


def test_a_face_finished_face_by_face_in_the_mount_file_outranks_every_rule_but_finish():
    """A STEP part's face given its finish by colour is more specific than "*", kind:, role: or part:
    (which choose faces); finish:NAME (which defines what the name means) still re-maps it."""
    assign = {"*": "absorber", "part:hood": "mirror", "kind:hood": "mirror", "role:mount": "mirror"}
    lib = {k: {} for k in ("absorber", "black-anodised", "ground-glass", "mirror")}
    own = FaceTag("hood", "hood", "mount", "black-anodised", face=3, assigned="colour #1a1a1a")
    assert finish_of(own, assign, lib) == "black-anodised"
    assert finish_of(FaceTag("hood", "hood", "mount", "black-anodised", face=4), assign, lib) == "mirror"
    assert finish_of(own, assign | {"finish:black-anodised": "ground-glass"}, lib) == "ground-glass"


def test_build_scene_objects_coatings_media():
    p = double_gauss()
    spec = scene_from_dict(scene_dict(
        coatings={"default": "perfect-ar", "surface-3": "uncoated"},
        objects=[{"type": "disk", "name": "dust", "centre_mm": [0, 0, -50], "radius_mm": 30, "tilt_deg": [10, 0],
                  "finish": "ground-glass"},
                 {"type": "rectangle", "name": "target", "centre_mm": [0, 0, -80], "width_mm": 10,
                  "height_mm": 5, "finish": "mirror"}]))
    scene = build_scene(p, double_gauss_mesh(p), spec)
    assert scene.optical[2].coating.kind == "uncoated" and scene.optical[0].coating.kind == "perfect-ar"
    assert "dust" in scene.part_names and "target" in scene.part_names
    i = [t.part for t in scene.mesh.tag_table].index("dust")
    assert scene.finish_of_tag[i] == "ground-glass" and scene.bsdf_of_tag[i] is not None
    # Media per wavelength: blue sees a larger index than red in N-SSK2 (surface 1's glass).
    n_after = scene.optical[0].n_after
    assert n_after.shape == (3,) and n_after[1] > n_after[0] > n_after[2] > 1.5
    np.testing.assert_array_equal(scene.optical[0].n_before, 1.0)
    # The cemented surface 4 has glass on both sides.
    assert scene.optical[3].n_before[0] > 1.5 and scene.optical[3].n_after[0] > 1.5
    assert scene.entrance_pupil_area_mm2 == pytest.approx(np.pi * (51.43 / 2) ** 2, rel=1e-3)
    # The dust plate sits at z = -50: the front opening and the emission disc move in front of it.
    assert scene.front_opening.z <= -50.0 - 30 * np.sin(np.radians(10)) + 1e-9


def test_stl_object_from_scene_file(tmp_path):
    """A `[[objects]] type = "mesh"` STL, placed and tilted, is traced like any mount part."""
    import tomli_w
    import trimesh

    from lensmount.physics.rays import RayBatch
    from lensmount.trace.tracer import FACE, Tracer
    from tests.trace.geometry import air_plane

    trimesh.creation.box(extents=(10.0, 10.0, 2.0)).export(tmp_path / "target.stl")
    data = scene_dict(objects=[{"type": "mesh", "name": "target", "path": "target.stl", "centre_mm": [0, 0, 50.0],
                                "tilt_deg": [0.0, 0.0], "finish": "ground-glass"}],
                      detector={"width_mm": 1, "height_mm": 1, "pixels": [1, 1], "z_mm": 1000.0})
    del data["assign"]
    (tmp_path / "scene.toml").write_text(tomli_w.dumps(data))
    spec = load_scene(tmp_path / "scene.toml")
    from lensmount.mesh import TaggedMesh

    empty = TaggedMesh(np.zeros((0, 3)), np.zeros((0, 3), int), np.zeros(0, np.int32), [])
    scene = build_scene(air_plane(), empty, spec)
    ev = Tracer(scene).next_event(RayBatch.make([[1.0, 2.0, 0.0]], [[0, 0, 1.0]]))
    assert ev.kind[0] == FACE and ev.position[0, 2] == pytest.approx(49.0, abs=1e-9)
    assert scene.finish_of_tag[ev.tag[0]] == "ground-glass"


def test_missing_mesh_file_is_an_input_error(tmp_path):
    from tests.trace.geometry import air_plane
    from lensmount.mesh import TaggedMesh

    spec = scene_from_dict(scene_dict(objects=[{"type": "mesh", "name": "x", "path": "nope.stl"}]),
                           base_dir=str(tmp_path))
    empty = TaggedMesh(np.zeros((0, 3)), np.zeros((0, 3), int), np.zeros(0, np.int32), [])
    with pytest.raises(InputError) as exc:
        build_scene(air_plane(), empty, spec)
    assert "objects.0.path" in str(exc.value)


@pytest.mark.slow
def test_step_object_from_scene_file(tmp_path):
    cq = pytest.importorskip("cadquery")
    from lensmount.mesh import TaggedMesh
    from lensmount.scene.build import object_meshes

    cq.exporters.export(cq.Workplane("XY").box(10, 10, 2), str(tmp_path / "plate.step"))
    spec = scene_from_dict(scene_dict(objects=[{"type": "mesh", "name": "plate", "path": "plate.step",
                                                "centre_mm": [0, 0, 20.0], "finish": "mirror"}]),
                           base_dir=str(tmp_path))
    (mesh,) = object_meshes(spec)
    assert isinstance(mesh, TaggedMesh) and len(mesh.triangles) >= 12
    np.testing.assert_allclose(mesh.vertices.min(axis=0), [-5, -5, 19], atol=1e-6)
    np.testing.assert_allclose(mesh.vertices.max(axis=0), [5, 5, 21], atol=1e-6)
