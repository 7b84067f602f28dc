"""The recipes of docs/architecture.md, done once: a source kind and a template kind added in
files of their own (beam_source.py, knife_ring.py) work through the project's own machinery."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "trace"))

import beam_source  # noqa: E402
from geometry import air_plane, mech_scene, scene_dict  # noqa: E402
from knife_ring import KnifeRing  # noqa: E402

from lensmount.design.scene import scene_from_dict  # noqa: E402
from lensmount.errors import InputError  # noqa: E402
from lensmount.integrators.forward import forward_pass  # noqa: E402
from lensmount.mesh import TaggedMesh  # noqa: E402
from lensmount.scene import primitives  # noqa: E402
from lensmount.scene.build import build_scene  # noqa: E402
from lensmount.physics.sources import SOURCE_KINDS  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def beam_kind():
    beam_source.register()
    yield
    del SOURCE_KINDS["beam"]


def test_a_registered_source_kind_is_read_from_a_scene_file_with_its_own_keys():
    spec = scene_from_dict(scene_dict(source={"type": "beam", "off_axis_deg": 0.0, "beam_radius_mm": 2.0}))
    assert spec.source.at_infinity and spec.source.beam_radius_mm == 2.0
    with pytest.raises(InputError) as err:  # its keys are checked like the built-in kinds'
        scene_from_dict(scene_dict(source={"type": "beam", "off_axis_deg": 0.0, "beam_radius": 2.0}))
    assert err.value.field == "source.beam_radius" and "beam_radius_mm" in err.value.detail
    with pytest.raises(InputError) as err:  # and another kind's keys name that kind
        scene_from_dict(scene_dict(source={"type": "beam", "off_axis_deg": 0.0, "beam_radius_mm": 2.0,
                                           "limb_darkening": True}))
    assert "applies to type = 'sun' only" in err.value.detail


def test_the_new_source_delivers_its_flux_through_an_open_aperture():
    """A 2 mm beam through an empty tube onto a detector that catches all of it: the detector
    receives π r² (E·mm²), whatever the tilt's share of the opening (energy conservation)."""
    mesh = primitives.tube(-5.0, 60.0, 15.0, 16.0)
    detector = {"width_mm": 20.0, "height_mm": 20.0, "pixels": [4, 4], "z_mm": 50.0}
    for off_axis in (0.0, 5.0):
        scene = mech_scene(mesh, detector=detector,
                           source={"type": "beam", "off_axis_deg": off_axis, "azimuth_deg": 90.0,
                                   "beam_radius_mm": 2.0})
        est = forward_pass(scene, Tracer(scene), n_photons=20_000, seed=3, pass_index=0)
        total = float(est.part_flux.sum())
        assert total == pytest.approx(math.pi * 2.0**2, rel=1e-9)


def test_a_template_in_its_own_file_builds_a_valid_tagged_solid():
    """The CAD layer's generic path (revolve, face roles from the profile, tessellation with a tag
    per CAD face) takes the new template as it takes the built-in ones."""
    from lensmount.cad.tessellate import tessellate_part
    from lensmount.templates.profile import face_roles

    ring = KnifeRing(z=10.0, bore_radius=8.0, outer_radius=14.0, thickness=1.5)
    solid = ring.build()
    assert solid.is_valid
    roles = face_roles(solid, ring.segments())
    assert ("vane-edge", -1) in roles
    mesh = tessellate_part(solid, "knife-ring-1", "vane", "black-anodised", roles, 0.05, 5.0)
    assert isinstance(mesh, TaggedMesh)
    edge = [k for k, t in enumerate(mesh.tag_table) if t.role == "vane-edge"]
    assert len(edge) == 1 and np.isin(mesh.tags, edge).any()
    r = np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1])
    assert r.min() == pytest.approx(8.0, abs=0.05) and r.max() == pytest.approx(14.0, abs=1e-6)
