"""A mirror surface in the non-sequential tracer: specular reflection at the analytic profile, weight R."""

from __future__ import annotations

import numpy as np

from tests.trace.geometry import make_scene
from lensmount.cad.mesh import FaceTag, TaggedMesh
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.optics.profiles import Profile
from lensmount.scene.primitives import _cap
from lensmount.trace.rays import RayBatch
from lensmount.trace.tracer import Tracer


def test_a_paraboloid_mirror_sends_every_parallel_ray_through_its_focus_with_weight_r():
    # concave paraboloid R = -200 (f = 100) at z = 0; the light returns towards -z
    mirror = Surface(radius=-200.0, conic=-1.0, thickness=-100.0, mirror=True, is_stop=True,
                     clear_semi_diameter=40.0, mechanical_semi_diameter=40.0, coating="R=0.9")
    p = Prescription((mirror,), Aperture("epd", 80.0))
    v, t = _cap(Profile.of(mirror), 0.0, 40.0, 12, 48)
    mesh = TaggedMesh(v, t, np.zeros(len(t), np.int32),
                      [FaceTag("mirror-1", "mirror", "optical", "polished", surface=0, face=0)])
    scene = make_scene(p, mesh, detector={"width_mm": 1.0, "height_mm": 1.0, "pixels": [1, 1], "z_mm": -1.0e4})
    rng = np.random.default_rng(3)
    n = 2000
    r = 38.0 * np.sqrt(rng.random(n))
    phi = 2 * np.pi * rng.random(n)
    o = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n, -50.0)])
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    ev = Tracer(scene).next_event(RayBatch.make(o, d))
    assert not ev.lost.any()
    np.testing.assert_allclose(ev.weight, 0.9, rtol=1e-12)
    assert np.all(ev.direction[:, 2] < 0.0)
    # every reflected ray passes through the focus (0, 0, -100): a paraboloid has no spherical aberration
    s = (-100.0 - ev.position[:, 2]) / ev.direction[:, 2]
    at_focus = ev.position + s[:, None] * ev.direction
    assert np.max(np.hypot(at_focus[:, 0], at_focus[:, 1])) < 1e-8
