"""Scene is strictly typed: what the physics reads is required and checked, never defaulted."""

import math

import numpy as np
import pytest

from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.scene.scene import Effects, Scene
from lensmount.physics.detector import Detector


def _mesh():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    return TaggedMesh(v, np.array([[0, 1, 2]]), np.zeros(1, np.int32), [FaceTag("plate", "object", "object", "x")])


def _kwargs(**over):
    kw = dict(mesh=_mesh(), optical=[], bsdf_of_tag=[None], source=None, detector=Detector(1, 1, 1, 1, 10.0),
              wavelengths_um=np.array([0.55]), effects=Effects(True, False, False),
              entrance_pupil_area_mm2=math.pi, solid_index_of_tag=np.ones((1, 1)),
              solid_absorption_of_tag=np.zeros((1, 1)))
    kw.update(over)
    return kw


def test_a_complete_scene_builds_with_no_warnings():
    scene = Scene(**_kwargs())
    assert scene.warnings == [] and scene.solid_index_of_tag.shape == (1, 1)


@pytest.mark.parametrize("missing", ["solid_index_of_tag", "solid_absorption_of_tag", "entrance_pupil_area_mm2", "effects"])
def test_fields_the_physics_needs_have_no_default(missing):
    kw = _kwargs()
    del kw[missing]
    with pytest.raises(TypeError, match=missing):
        Scene(**kw)


@pytest.mark.parametrize("over", [
    {"solid_index_of_tag": np.ones((2, 1))},           # one row per tag
    {"solid_index_of_tag": np.ones((1, 3))},           # one column per wavelength
    {"solid_index_of_tag": np.full((1, 1), 0.5)},      # an index below 1
    {"solid_index_of_tag": np.full((1, 1), np.nan)},
    {"solid_absorption_of_tag": np.zeros((2, 1))},
    {"solid_absorption_of_tag": np.full((1, 1), -1e-3)},  # absorption cannot add light
    {"solid_absorption_of_tag": np.full((1, 1), np.inf)},
    {"entrance_pupil_area_mm2": 0.0},                   # would read as a stray fraction of 0
    {"entrance_pupil_area_mm2": float("nan")},
    {"bsdf_of_tag": []},
    {"finish_of_tag": ["a", "b"]},
    {"wavelengths_um": np.array([])},
])
def test_inconsistent_fields_are_refused(over):
    with pytest.raises(ValueError):
        Scene(**_kwargs(**over))


def test_effects_must_be_effects():
    with pytest.raises(TypeError):
        Scene(**_kwargs(effects={"scatter": True}))
