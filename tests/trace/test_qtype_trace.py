"""The tracer's analytic refinement on a Forbes Q-type face: facet hits refined onto the surface."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.trace.geometry import make_scene
from lensmount.optics.io.zemax import read_zmx
from lensmount.optics.profiles import Profile
from lensmount.physics.rays import RayBatch
from lensmount.scene import primitives
from lensmount.trace.tracer import Tracer

ASL5040 = Path(__file__).parents[1] / "optics" / "corpus" / "thorlabs-ASL5040-UV-qbfs-utf16.zmx"


def test_refined_hits_lie_on_the_qbfs_face_and_agree_with_the_sequential_trace():
    """Rays at every height and at angles up to grazing the rim: where the tracer reports the Q-type
    face, the point lies on it to 1e-9 mm, the normal is Profile.normal's, and the crossing is the
    sequential trace's own (Profile.intersect) to 1e-9 mm."""
    p = read_zmx(ASL5040)
    mesh = primitives.lens_elements(p, [25.0, 25.0], rings=24, segments=96)
    tracer = Tracer(make_scene(p, mesh, detector={"width_mm": 60, "height_mm": 60, "pixels": [4, 4]}))
    rng = np.random.default_rng(11)
    n = 3000
    h = 24.0 * np.sqrt(rng.uniform(0, 1, n))
    phi = rng.uniform(0, 2 * np.pi, n)
    tilt = np.radians(rng.uniform(0, 80, n))  # up to 10° from grazing the plane of the rim
    az = rng.uniform(0, 2 * np.pi, n)
    o = np.column_stack([h * np.cos(phi), h * np.sin(phi), np.full(n, -30.0)])
    d = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    o = o - 20.0 * d  # start well in front, aimed at the face
    hits = tracer.intersect(RayBatch.make(o, d))
    prof = Profile.of(p.surfaces[0])
    on = hits.surface == 0
    assert on.sum() > n // 5  # the steepest start beside the lens
    q = hits.point[on]
    r2 = q[:, 0] ** 2 + q[:, 1] ** 2
    assert np.max(np.abs(q[:, 2] - prof.sag(r2))) < 1e-9
    assert np.max(np.abs(np.abs(np.einsum("ij,ij->i", hits.normal[on], prof.normal(q))) - 1.0)) < 1e-12
    t_seq = prof.intersect(o[on], d[on])
    assert np.max(np.abs(o[on] + t_seq[:, None] * d[on] - q)) < 1e-9
    assert np.isfinite(hits.point).all()
