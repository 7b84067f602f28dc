"""Hit points seen from inside glass carry 1/n², a detector in a medium of index n_d takes n_d² (radiance/n² is
what crosses an interface)."""

import math

import numpy as np
import pytest
import trimesh

from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.integrators.photon_mapping.media import detector_radiance_factor
from lensmount.optics.glass import refractive_index
from lensmount.physics.detector import Detector
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.scene.build import solid_index_of_tag


class _Scene:
    def __init__(self, mesh, index, medium_index=()):
        self.mesh, self.solid_index_of_tag = mesh, index
        self.detector = Detector(10.0, 10.0, 4, 4, 60.0, medium_index=medium_index)


def _cube_lens():
    box = trimesh.creation.box((10.0, 10.0, 10.0))
    tags = [FaceTag("lens-1", "lens", "optical", "x", surface=0), FaceTag("lens-1", "lens", "lens-edge", "ground-glass"),
            FaceTag("barrel", "barrel", "mount", "black-anodised")]
    z = box.triangles_center[:, 2]
    tag = np.where(z < -4.9, 0, 1)
    mesh = TaggedMesh(box.vertices, box.faces, tag, tags)
    lens = Prescription((Surface(math.inf, 10.0, "N-BK7", is_stop=True), Surface(math.inf, 50.0)), Aperture("epd", 5.0),
                        (0.4861327, 0.5875618))
    return mesh, solid_index_of_tag(lens, mesh, np.array(lens.wavelengths_um))


def test_solid_index_is_the_lens_glass_for_lens_tags_and_one_for_mounts():
    mesh, index = _cube_lens()
    bk7 = refractive_index("N-BK7", [0.4861327, 0.5875618])
    np.testing.assert_allclose(index[0], bk7)
    np.testing.assert_allclose(index[1], bk7)
    np.testing.assert_allclose(index[2], 1.0)


def test_only_rays_leaving_the_glass_get_one_over_n_squared():
    mesh, index = _cube_lens()
    scene = _Scene(mesh, index)
    side = np.flatnonzero(mesh.tags == 1)
    # the +x face: triangles whose centroid has x = +5
    centres = mesh.vertices[mesh.triangles[side]].mean(axis=1)
    prim = side[np.isclose(centres[:, 0], 5.0)][:2]
    outward = np.tile([1.0, 0.0, 0.0], (2, 1))
    factor = detector_radiance_factor(scene, np.vstack([outward[:1], -outward[:1]]), np.ones(2, int), prim, np.array([1, 1]))
    n = refractive_index("N-BK7", 0.5875618)
    assert factor[0] == pytest.approx(1.0 / n**2)  # travelling outward: it was inside the glass
    assert factor[1] == 1.0  # arriving from the air


def test_mechanical_parts_and_meshless_tracers_keep_factor_one():
    mesh, index = _cube_lens()
    scene = _Scene(mesh, index)
    assert detector_radiance_factor(scene, np.array([[1.0, 0, 0]]), np.array([2]), np.array([0]), np.array([0]))[0] == 1.0
    assert detector_radiance_factor(scene, np.array([[1.0, 0, 0]]), np.array([1]), None, np.array([0]))[0] == 1.0


def test_primitive_lens_solids_wind_outward():
    """The n² rule reads 'inside' from the winding, so test-scene lenses must follow the mesh rule."""
    from lensmount.scene.primitives import lens_elements

    lens = Prescription((Surface(51.68, 6.0, "N-BK7", is_stop=True), Surface(math.inf, 96.0)), Aperture("epd", 25.0))
    m = lens_elements(lens, [12.5, 12.5], rings=8, segments=32)
    solid = trimesh.Trimesh(m.vertices, m.triangles, process=True)
    assert solid.is_winding_consistent and solid.volume > 0


def test_a_detector_in_water_takes_n_water_squared_times_the_radiance_seen_from_air_or_glass():
    """Radiance / n² is invariant: a face of radiance L in air is seen as n_w² L from the water the detector
    is immersed in, and a lens edge seen from inside glass of index n as (n_w / n)² L_glass."""
    mesh, index = _cube_lens()
    n_w = (1.337, 1.333)   # water at the two wavelengths
    scene = _Scene(mesh, index, n_w)
    side = np.flatnonzero(mesh.tags == 1)
    centres = mesh.vertices[mesh.triangles[side]].mean(axis=1)
    prim = side[np.isclose(centres[:, 0], 5.0)][:1]
    leaving = detector_radiance_factor(scene, np.array([[1.0, 0, 0]]), np.array([1]), prim, np.array([1]))[0]
    assert leaving == pytest.approx((n_w[1] / refractive_index("N-BK7", 0.5875618)) ** 2)
    metal = detector_radiance_factor(scene, np.array([[1.0, 0, 0]] * 2), np.array([2, 2]), np.array([0, 0]),
                                     np.array([0, 1]))
    np.testing.assert_allclose(metal, np.square(n_w))
