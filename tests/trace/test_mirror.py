"""A mirror surface in the non-sequential tracer: specular reflection at the analytic profile, weight R."""

from __future__ import annotations

import numpy as np

from tests.trace.geometry import make_scene
from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.optics.profiles import Profile
from lensmount.scene.primitives import _cap
from lensmount.physics.rays import RayBatch
from lensmount.trace.tracer import Tracer
from lensmount.optics.realrays import trace


def test_a_paraboloid_mirror_sends_every_parallel_ray_through_its_focus_with_weight_r():
    # concave paraboloid R = -200 (f = 100) at z = 0; the light returns towards -z
    mirror = Surface(radius=-200.0, conic=-1.0, thickness=-100.0, mirror=True, is_stop=True,
                     clear_semi_diameter=40.0, mechanical_semi_diameter=40.0, coating="R=0.9")
    p = Prescription((mirror,), Aperture("epd", 80.0))
    v, t = _cap(Profile.of(mirror), 0.0, 40.0, 12, 48)
    mesh = TaggedMesh(v, t, np.zeros(len(t), np.int32),
                      [FaceTag("mirror-1", "mirror", "optical", "polished", surface=0, face=0)])
    scene = make_scene(p, mesh, detector={"width_mm": 1.0, "height_mm": 1.0, "pixels": [1, 1], "z_mm": -1.0e4})
    o, d = _collimated_disc(38.0, 2000, seed=3)
    ev = Tracer(scene).next_event(RayBatch.make(o, d))
    assert not ev.lost.any()
    np.testing.assert_allclose(ev.weight, 0.9, rtol=1e-12)
    assert np.all(ev.direction[:, 2] < 0.0)
    # every reflected ray passes through the focus (0, 0, -100): a paraboloid has no spherical aberration
    s = (-100.0 - ev.position[:, 2]) / ev.direction[:, 2]
    at_focus = ev.position + s[:, None] * ev.direction
    assert np.max(np.hypot(at_focus[:, 0], at_focus[:, 1])) < 1e-8


def _mirror_scene(surfaces, caps, epd, detector_z=-1.0e4, hole=False, **scene):
    """A scene of analytic surfaces meshed as caps [(surface index, radius)] (no mount); hole: the
    first cap without its central fan (a hole of a quarter of its radius)."""
    p = Prescription(tuple(surfaces), Aperture("epd", epd))
    zs = p.vertex_z
    vs, ts, tags, table = [], [], [], []
    offset = 0
    for k, (i, radius) in enumerate(caps):
        v, t = _cap(Profile.of(p.surfaces[i]), zs[i], radius, 16, 64)
        if hole and k == 0:
            t = t[64:]
        vs.append(v)
        ts.append(t + offset)
        tags.append(np.full(len(t), k, np.int32))
        table.append(FaceTag(f"part-{k}", "lens", "optical", "polished", surface=i, face=0))
        offset += len(v)
    mesh = TaggedMesh(np.vstack(vs), np.vstack(ts), np.concatenate(tags), table)
    det = {"width_mm": 1.0, "height_mm": 1.0, "pixels": [1, 1], "z_mm": detector_z}
    return p, make_scene(p, mesh, detector=det, **scene)


def _collimated_disc(radius, n, seed):
    """n rays parallel to +z, uniform over a disc of `radius` at z = -50 (origins, directions)."""
    rng = np.random.default_rng(seed)
    r = radius * np.sqrt(rng.random(n))
    phi = 2 * np.pi * rng.random(n)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n, -50.0)]), np.tile([0.0, 0.0, 1.0], (n, 1))


def _at_plane(position, direction, z):
    s = (z - position[:, 2]) / direction[:, 2]
    return position + s[:, None] * direction


def test_a_spherical_mirror_follows_the_sequential_trace_and_reflects_protected_aluminium_by_default():
    # concave sphere R = -200: paraxial focus at R/2 = 100 mm in front of it (light returns along -z)
    mirror = Surface(radius=-200.0, thickness=-100.0, mirror=True, is_stop=True, clear_semi_diameter=30.0)
    p, scene = _mirror_scene([mirror], [(0, 30.0)], 60.0)
    o, d = _collimated_disc(29.0, 500, seed=5)
    ev = Tracer(scene).next_event(RayBatch.make(o, d))
    assert not ev.lost.any()
    # default reflectance: protected aluminium, the documented 0.90 (no constant coating given)
    np.testing.assert_allclose(ev.weight, 0.90, rtol=1e-12)
    seq = trace(p, o, d, clip=False)
    np.testing.assert_allclose(_at_plane(ev.position, ev.direction, -100.0), seq.image_points, atol=1e-9)
    # near the axis the rays cross at the analytic focus R/2; farther out spherical aberration pulls them in
    r = np.hypot(o[:, 0], o[:, 1])
    near = r < 2.0
    zc = -100.0 + 0.0  # paraxial focus
    lsa = -(r[near] ** 2) / (4 * 200.0)  # third-order longitudinal aberration of a sphere, h²/(4R) toward it
    cross = ev.position[near, 2] - ev.position[near, 0] * ev.direction[near, 2] / ev.direction[near, 0]
    np.testing.assert_allclose(cross, zc - lsa, atol=1e-3)


def test_a_constant_coating_sets_a_mirrors_reflectance():
    mirror = Surface(radius=-200.0, thickness=-100.0, mirror=True, is_stop=True, clear_semi_diameter=30.0,
                     coating="R=0.97")
    _, scene = _mirror_scene([mirror], [(0, 30.0)], 60.0)
    o = np.array([[1.0, 2.0, -50.0], [-10.0, 3.0, -50.0]])
    ev = Tracer(scene).next_event(RayBatch.make(o, np.tile([0.0, 0.0, 1.0], (2, 1))))
    np.testing.assert_allclose(ev.weight, 0.97, rtol=1e-12)


def test_a_mangin_secondary_met_travelling_minus_z_refracts_with_the_files_media_swapped():
    # a Cassegrain whose secondary is a Mangin mirror: the light meets its glass front travelling
    # -z (after the primary), reflects at the coated back and leaves through the front again,
    # through the primary's hole to the image plane at z = 0; the media on each side of the
    # Mangin's front are the file's swapped (air on its +z side), which the tracer must follow
    primary = Surface(radius=-400.0, thickness=-150.0, mirror=True, is_stop=True)
    front = Surface(radius=-150.0, thickness=-4.0, material="N-BK7")
    back = Surface(radius=-165.0, thickness=4.0, material="N-BK7", mirror=True)
    again = Surface(radius=-150.0, thickness=150.0, material="AIR")
    p, scene = _mirror_scene([primary, front, back, again], [(0, 30.0), (1, 10.0), (2, 10.0)], 60.0,
                             hole=True)
    rng = np.random.default_rng(7)
    n = 400
    r = 12.0 + 13.0 * rng.random(n)           # outside the primary's 7.5 mm hole
    phi = 2 * np.pi * rng.random(n)
    o = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n, -20.0)])
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    ev = Tracer(scene).next_event(RayBatch.make(o, d))
    assert not ev.lost.any() and np.all(ev.direction[:, 2] > 0)
    seq = trace(p, o, d, clip=False)
    assert not seq.vignetted.any()
    np.testing.assert_allclose(_at_plane(ev.position, ev.direction, p.image_z), seq.image_points, atol=1e-8)
    np.testing.assert_allclose(ev.direction, seq.directions[-1], atol=1e-12)


def test_the_scenes_default_coating_is_for_glass_and_leaves_a_mirror_its_reflectance():
    mirror = Surface(radius=-200.0, thickness=-100.0, mirror=True, is_stop=True, clear_semi_diameter=30.0)
    _, scene = _mirror_scene([mirror], [(0, 30.0)], 60.0, coatings={"default": "R=0.01"})
    o = np.array([[1.0, 2.0, -50.0]])
    ev = Tracer(scene).next_event(RayBatch.make(o, [[0.0, 0.0, 1.0]]))
    np.testing.assert_allclose(ev.weight, 0.90, rtol=1e-12)
    _, scene = _mirror_scene([mirror], [(0, 30.0)], 60.0, coatings={"default": "R=0.01", "surface-1": "R=0.8"})
    ev = Tracer(scene).next_event(RayBatch.make(o, [[0.0, 0.0, 1.0]]))
    np.testing.assert_allclose(ev.weight, 0.80, rtol=1e-12)
