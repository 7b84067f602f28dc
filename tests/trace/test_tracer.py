"""The tracer's geometry rules: no leaks at seams, thin parts from both sides, no self-hits,
analytic refinement on optical faces, nearest-wins with the detector."""

import math

import numpy as np
import pytest

from tests.trace.geometry import double_gauss, double_gauss_mesh, make_scene, mech_scene, window
from lensmount.mesh import TaggedMesh
from lensmount.scene import primitives
from lensmount.physics.rays import RayBatch
from lensmount.trace.tracer import DETECTOR, FACE, GONE, Tracer


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_closed_icosphere_does_not_leak_at_vertices_and_edges():
    sph = primitives.sphere((3.0, -2.0, 40.0), 25.0, subdivisions=3)
    tr = Tracer(mech_scene(sph))
    v, t = sph.vertices, sph.triangles
    centre = np.array([3.0, -2.0, 40.0])
    # Aim exactly at every vertex, every edge midpoint and every face centroid, from the centre
    # and from an off-centre point.
    edges = 0.5 * (v[t[:, [0, 1, 2]]] + v[t[:, [1, 2, 0]]]).reshape(-1, 3)
    targets = np.vstack([v, edges, v[t].mean(axis=1)])
    for src in (centre, centre + np.array([5.0, 7.0, -3.0])):
        o = np.broadcast_to(src, targets.shape).copy()
        hits = tr.intersect(RayBatch.make(o, targets - o))
        assert np.all(np.isfinite(hits.t)), "a ray aimed at a seam escaped"
        assert not hits.lost.any()
        r = np.linalg.norm(hits.point - centre, axis=1)
        assert r.max() <= 25.0 + 1e-9 and r.min() > 25.0 * 0.98


def test_box_corners_edges_random_interior():
    box = primitives.box((-10, -10, 0), (10, 10, 20), inward=True)
    tr = Tracer(mech_scene(box))
    rng = np.random.default_rng(3)
    n = 20000
    o = rng.uniform([-9.9, -9.9, 0.1], [9.9, 9.9, 19.9], (n, 3))
    d = _unit(rng.normal(size=(n, 3)))
    corners = np.array([[x, y, z] for x in (-10, 10) for y in (-10, 10) for z in (0, 20)], float)
    o2 = np.zeros((8, 3)) + [0, 0, 10]
    ev = tr.next_event(RayBatch.make(np.vstack([o, o2]), np.vstack([d, corners - o2])), rng)
    assert np.all(ev.kind == FACE)
    # Every event point lies on the box (one coordinate on a wall, all inside).
    p = ev.position
    on_wall = np.isclose(np.abs(p[:, 0]), 10, atol=1e-9) | np.isclose(np.abs(p[:, 1]), 10, atol=1e-9) \
        | np.isclose(p[:, 2], 0, atol=1e-9) | np.isclose(p[:, 2], 20, atol=1e-9)
    assert on_wall.all()
    # The reported normal faces the incoming ray.
    assert np.all(np.einsum("ij,ij->i", ev.normal, ev.direction) < 0)


def test_knife_edge_50um_is_hit_from_both_sides_and_no_self_hit():
    plate = primitives.box((-5, -5, -0.025), (5, 5, 0.025), part="diaphragm", kind="diaphragm",
                           role="diaphragm-edge")
    tr = Tracer(mech_scene(plate, detector={"width_mm": 1, "height_mm": 1, "pixels": [1, 1], "z_mm": 3000.0}))
    x = np.linspace(-4.9, 4.9, 101)
    o_top = np.column_stack([x, 0.3 * x, np.full_like(x, -10.0)])
    o_bot = np.column_stack([x, 0.3 * x, np.full_like(x, 10.0)])
    up = np.tile([0.0, 0.0, 1.0], (len(x), 1))
    h1 = tr.intersect(RayBatch.make(o_top, up))
    h2 = tr.intersect(RayBatch.make(o_bot, -up))
    np.testing.assert_allclose(h1.point[:, 2], -0.025, atol=1e-12)
    np.testing.assert_allclose(h2.point[:, 2], 0.025, atol=1e-12)
    # Leaving the face it hit (reflected back) the ray must not see that face again ...
    back = tr.intersect(RayBatch.make(h1.point, -up))
    assert np.all(~np.isfinite(back.t))
    # ... but going on through the plate it meets the other face 50 µm further.
    through = tr.intersect(RayBatch.make(h1.point, up))
    np.testing.assert_allclose(through.t, 0.05, atol=1e-9)
    # The 50 µm rim itself, hit edge-on from the side at grazing and normal angles.
    o_side = np.column_stack([np.full(5, -20.0), np.zeros(5), np.linspace(-0.02, 0.02, 5)])
    side = tr.intersect(RayBatch.make(o_side, np.tile([1.0, 0, 0], (5, 1))))
    np.testing.assert_allclose(side.point[:, 0], -5.0, atol=1e-9)


@pytest.mark.parametrize("angle_deg", [89.99, 89.9, 80.0])
def test_grazing_rays_on_a_plane(angle_deg):
    plate = primitives.box((-50, -50, -1), (50, 50, 0))
    tr = Tracer(mech_scene(plate))
    a = math.radians(angle_deg)
    n = 200
    x0 = np.linspace(-40, 40, n)
    d = np.tile([math.sin(a), 0.0, -math.cos(a)], (n, 1))
    o = np.column_stack([x0, np.linspace(-30, 30, n), np.full(n, 0.0)]) - 5.0 * d
    hits = tr.intersect(RayBatch.make(o, d))
    ok = np.isfinite(hits.t)
    assert ok.all()
    np.testing.assert_allclose(hits.point[:, 2], 0.0, atol=1e-9)
    # Scatter back out at grazing angle: the plane must not be hit again.
    out = np.tile([math.sin(a), 0.0, math.cos(a)], (n, 1))
    again = tr.intersect(RayBatch.make(hits.point, out))
    assert np.all(~np.isfinite(again.t) | (again.point[:, 0] >= 49.99))


def test_optical_hits_are_on_the_analytic_surface():
    p = double_gauss()
    scene = make_scene(p, double_gauss_mesh(p, rings=6, segments=24))  # coarse facets: sag error ~ 1 mm
    tr = Tracer(scene)
    rng = np.random.default_rng(0)
    n = 5000
    r = 40.0 * np.sqrt(rng.random(n))
    ph = 2 * np.pi * rng.random(n)
    o = np.column_stack([r * np.cos(ph), r * np.sin(ph), np.full(n, -30.0)])
    d = _unit(np.column_stack([0.02 * rng.normal(size=n), 0.02 * rng.normal(size=n), np.ones(n)]))
    h = tr.intersect(RayBatch.make(o, d))
    assert np.all(h.surface == 0)
    s1 = scene.optical[0]
    p_local = h.point - [0, 0, s1.z_vertex]
    sag = s1.profile.sag(p_local[:, 0] ** 2 + p_local[:, 1] ** 2)
    np.testing.assert_allclose(p_local[:, 2], sag, atol=1e-11)
    # The normal is the analytic one: radial through the sphere's centre.
    centre = np.array([0, 0, s1.z_vertex + 1.0 / s1.profile.curvature])
    radial = _unit(centre - h.point)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", radial, h.normal)), 1.0, atol=1e-12)


def test_detector_nearest_wins_and_back_side_blocks():
    blocker = primitives.disk((0, 0, 50), 2.0, part="dust")
    scene = mech_scene(blocker, detector={"width_mm": 20, "height_mm": 20, "pixels": [4, 4], "z_mm": 100.0})
    tr = Tracer(scene)
    o = np.array([[0.0, 0, 0], [5.0, 5.0, 0.0], [5.0, 5.0, 200.0], [30.0, 0.0, 0.0]])
    d = np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, -1.0], [0, 0, 1.0]])
    ev = tr.next_event(RayBatch.make(o, d))
    assert list(ev.kind) == [FACE, DETECTOR, GONE, GONE]
    assert ev.position[1] == pytest.approx([5.0, 5.0, 100.0])
    assert ev.pixel[1] == 3 * 4 + 3 and ev.pixel[0] == -1


def test_window_fresnel_weight_and_ghost_branch():
    """Plane BK7 window at normal incidence, uncoated: ghosts off -> weight T² exactly;
    ghosts on -> the reflected share estimates the two-surface reflectance (bulk absorption off:
    Fresnel alone)."""
    p = window()
    n_glass = float(make_scene(p, TaggedMesh.concatenate([])).optical[0].n_after[0])
    r = ((n_glass - 1) / (n_glass + 1)) ** 2
    mesh = primitives.lens_elements(p, [20.0, 20.0], rings=4, segments=32)
    det = {"width_mm": 100, "height_mm": 100, "pixels": [1, 1]}
    off = make_scene(p, mesh, detector=det, coatings={"default": "uncoated"}, effects={"absorption": False})
    n = 40000
    o = np.column_stack([np.zeros(n), np.zeros(n), np.full(n, -10.0)])
    o[:, :2] = np.random.default_rng(1).uniform(-10, 10, (n, 2))
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    ev = Tracer(off).next_event(RayBatch.make(o, d))
    assert np.all(ev.kind == DETECTOR)
    np.testing.assert_allclose(ev.weight, (1 - r) ** 2, rtol=1e-12)
    on = make_scene(p, mesh, detector=det, coatings={"default": "uncoated"},
                    effects={"ghosts": True, "absorption": False})
    ev = Tracer(on).next_event(RayBatch.make(o, d), np.random.default_rng(2))
    assert np.all(ev.weight == 1.0)
    back = ev.kind == GONE  # reflected out of the front, toward -z
    # Incoherent plate reflectance: R + T² R / (1 − R²) ... = 2R / (1 + R).
    expected = 2 * r / (1 + r)
    sigma = math.sqrt(expected * (1 - expected) / n)
    assert abs(back.mean() - expected) < 4 * sigma
    assert np.all(ev.direction[back, 2] < 0)


def test_dead_and_nonfinite_rays_are_ignored():
    tr = Tracer(mech_scene(primitives.box((-1, -1, -1), (1, 1, 1))))
    o = np.array([[0, 0, -5.0], [np.nan, 0, 0], [0, 0, -5.0]])
    d = np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0]])
    rays = RayBatch.make(o, d)
    rays.alive[2] = False
    ev = tr.next_event(rays)
    assert list(ev.kind) == [FACE, GONE, GONE]
    assert np.all(np.isfinite(ev.position)) and np.all(np.isfinite(ev.weight))
    assert ev.weight[2] == 0.0


def test_a_ray_still_in_the_glass_after_the_interface_limit_is_absorbed_there_not_lost(monkeypatch):
    """Inside a BK7 window at 60° from the normal (past the 41° critical angle) a ray reflects
    totally from face to face, 8.7 mm sideways a bounce, until the plate's rim (a mechanical face).
    With the interface limit below its bounce count it counts as trapped: a ray circling an
    element's rim by total internal reflection never reaches the edge, and a real one is absorbed
    in the glass. Weight 0, GONE, not a numerical loss; with the real limit it meets the rim."""
    import lensmount.trace.tracer as tracer_module

    p = window()
    mesh = primitives.lens_elements(p, [20.0, 20.0], rings=4, segments=64)
    tracer = Tracer(make_scene(p, mesh, coatings={"default": "uncoated"}, effects={"absorption": False}))
    o = np.array([[-15.0, 0.3, 2.5]])
    d = np.array([[math.sin(math.radians(60.0)), 0.0, math.cos(math.radians(60.0))]])
    ev = tracer.next_event(RayBatch.make(o, d))
    assert ev.kind[0] == FACE and not ev.lost[0] and ev.weight[0] == 1.0  # the rim, after total reflections
    monkeypatch.setattr(tracer_module, "_MAX_OPTICAL", 2)
    ev = tracer.next_event(RayBatch.make(o, d))
    assert ev.kind[0] == GONE and not ev.lost[0] and ev.weight[0] == 0.0
    assert 0.0 <= ev.position[0, 2] <= 5.0  # where it was: on a face of the glass
