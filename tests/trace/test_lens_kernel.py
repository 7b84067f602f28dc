"""The compiled walk through the lens (lensmount.trace.lens_kernel) against independent references.

- Its coating reflectance is the thin-film formulas of `trace.interfaces` (numpy, tested there
  against Fresnel's equations), and its Fresnel-branch uniform is `Streams.at`'s number.
- Its clear bore never clears a segment that meets a mechanical triangle: checked against this
  suite's own float64 Möller–Trumbore (`test_exactness.reference_nearest`), and it does clear
  the segments of an axial beam (else the walk would never run).
"""

from pathlib import Path

import numpy as np
import pytest

from tests.trace.geometry import double_gauss, double_gauss_mesh
from tests.trace.test_exactness import reference_nearest
from lensmount.trace import lens_kernel
from lensmount.physics.interfaces import parse_coating, reflectance
from lensmount.physics.sampler import Streams


@pytest.mark.parametrize("name", ["perfect-ar", "uncoated", "mgf2-quarter-wave", "R=0.02"])
def test_compiled_reflectance_is_the_thin_film_formulas(name):
    rng = np.random.default_rng(3)
    n = 400
    n1 = rng.choice([1.0, 1.5168, 1.7847], n)
    n2 = rng.choice([1.0, 1.5168, 1.7847], n)
    cos_i = rng.random(n)
    wl = rng.uniform(0.4, 0.7, n)
    coating = parse_coating(name)
    want = reflectance(n1, n2, cos_i, coating, wl)
    code = lens_kernel.COATING_CODES[coating.kind]
    got = np.array([lens_kernel.reflectance(a, b, c, code, coating.reflectance, w) for a, b, c, w in zip(n1, n2, cos_i, wl)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    if name == "uncoated":  # and Fresnel at normal incidence, air to BK7
        assert lens_kernel.reflectance(1.0, 1.5168, 1.0, code, 0.0, 0.55) == pytest.approx((0.5168 / 2.5168) ** 2, rel=1e-12)


def test_compiled_uniform_is_the_streams_number():
    s = Streams(7, "forward", np.arange(50))
    for dim in (0, 5, (1 << 20) + 3):
        got = np.array([lens_kernel.uniform(k, dim) for k in s.keys])
        assert np.array_equal(got, s.at(None, dim))


def test_clear_bore_never_clears_a_segment_that_meets_metal():
    """Segments from inside the bore that end within ±20 µm of a mechanical face (a point on a random
    triangle moved along its normal: half stop short of the metal, half end inside it), so the
    verdict is decided at the metal's edge, where a bore table or margin off by microns would clear
    a segment through metal; and uniformly random ones through the bore, the diaphragm and the wall."""
    mesh = double_gauss_mesh(double_gauss(), rings=4, segments=24)
    mech = mesh.triangles[np.array([t.role != "optical" for t in mesh.tag_table])[mesh.tags]]
    corners = [mesh.vertices[mech[:, k]] for k in range(3)]
    z0, inv_h, table, margin = lens_kernel.clear_bore(*corners)
    rng = np.random.default_rng(11)
    n = 600
    k = rng.integers(0, len(mech), 2 * n)
    u, v = rng.random(2 * n), rng.random(2 * n)
    u, v = np.where(u + v > 1, 1 - u, u), np.where(u + v > 1, 1 - v, v)
    on = corners[0][k] + u[:, None] * (corners[1][k] - corners[0][k]) + v[:, None] * (corners[2][k] - corners[0][k])
    normal = np.cross(corners[1][k] - corners[0][k], corners[2][k] - corners[0][k])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)  # outward: the solids are closed, counter-clockwise
    b_near = on + rng.uniform(-0.02, 0.02, 2 * n)[:, None] * normal  # mm off the face (< 0: into the metal)
    a_near = np.column_stack([rng.uniform(-10, 10, (2 * n, 2)), on[:, 2] + rng.uniform(-40, 40, 2 * n)])
    a = np.vstack([np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(-30, 420, n)]), a_near])
    b = np.vstack([np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(-30, 420, n)]), b_near])
    a[: n // 3, :2] *= 0.4
    b[: n // 3, :2] *= 0.4
    length = np.linalg.norm(b - a, axis=1)
    d = (b - a) / length[:, None]
    t_hit, _ = reference_nearest(a, d, np.stack(corners, axis=1))
    clear = np.array([lens_kernel._clear(*a[i], *d[i], length[i], z0, inv_h, table, margin) for i in range(len(a))])
    assert not np.any(clear & (t_hit <= length)), "a segment through metal was cleared"
    near = np.arange(len(a)) >= n
    assert np.sum(near & (t_hit <= length)) > n // 2  # many near segments do meet the metal ...
    assert np.sum(near & clear) > n // 10  # ... and many that stop microns short of it are cleared
    assert clear.sum() > n // 5  # it does clear what is far from the metal
    assert np.sum(~clear & (t_hit > length)) > 0  # conservative, not a reference copy


def test_sequential_step_agrees_with_the_embree_path():
    """Wherever the analytic step says it is sure (from a glass surface, or from outside the lens),
    Embree's facets refined on the same line find the same surface at the same distance."""
    from tests.trace.geometry import make_scene
    from lensmount.trace.tracer import Tracer

    p = double_gauss()
    tracer = Tracer(make_scene(p, double_gauss_mesh(p, rings=12, segments=48, barrel=False)))
    rng = np.random.default_rng(5)
    o, d, left = [], [], []
    for k, s in enumerate(tracer.scene.optical):
        m = 1500
        r = 40.0 * np.sqrt(rng.random(m))
        phi = 2 * np.pi * rng.random(m)
        x, y = r * np.cos(phi), r * np.sin(phi)
        z = s.z_vertex + s.profile.sag(x * x + y * y)
        ok = np.isfinite(z)
        tilt = np.radians(80.0) * rng.random(m) ** 2
        sign = np.where(rng.random(m) < 0.8, 1.0, -1.0)  # mostly onward, some back toward the object
        az = 2 * np.pi * rng.random(m)
        dd = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), sign * np.cos(tilt)])
        o.append(np.column_stack([x, y, z])[ok])
        d.append(dd[ok])
        left.append(np.full(ok.sum(), k))
    o.append(np.column_stack([rng.uniform(-30, 30, (500, 2)), np.full(500, -40.0)]))  # from in front of the lens
    d.append(np.tile([0.0, 0.1, 1.0], (500, 1)) / np.hypot(1.0, 0.1))
    left.append(np.full(500, -1))
    o, d, left = np.concatenate(o), np.concatenate(d), np.concatenate(left)
    sure, t, s = tracer._sequential_step(left, o, d, np.full(len(o), np.inf))
    assert sure.mean() > 0.5  # the step does take most of them
    t_ref, prim, _, lost = tracer._optical_nearest(o[sure], d[sure], np.full(sure.sum(), np.inf))
    s_ref = np.where(prim >= 0, tracer._tri_surface[np.maximum(prim, 0)], -1)
    assert not lost.any()
    # A grazing ray can cross the arc of the surface it leaves again between two of its chords,
    # where no facet is: the analytic step is right there and Embree's facets are not a reference.
    s_step, t_step = s[sure], t[sure]
    regraze = (s_step == left[sure]) & (s_ref != s_step)
    assert regraze.sum() < 1e-3 * sure.sum()
    keep = ~regraze
    assert np.array_equal(s_step[keep], s_ref[keep])
    hit = np.isfinite(t_ref) & keep
    assert np.array_equal(np.isfinite(t_step[keep]), hit[keep])
    np.testing.assert_allclose(t_step[hit], t_ref[hit], rtol=0, atol=1e-9)


def test_a_ray_the_walk_lets_escape_meets_no_metal():
    """Rays from the image side back out through the front: those that end GONE (the walk proves
    most of them out of the mount's z range with the clear bore) cross no mechanical triangle
    on their last line, by the independent float64 Möller–Trumbore; the others meet the barrel."""
    from tests.trace.geometry import make_scene
    from lensmount.physics.rays import RayBatch
    from lensmount.trace.tracer import FACE, GONE, Tracer

    p = double_gauss()
    mesh = double_gauss_mesh(p, rings=6, segments=24)
    tracer = Tracer(make_scene(p, mesh, detector={"width_mm": 10, "height_mm": 10, "pixels": [1, 1], "z_mm": 600.0}))
    rng = np.random.default_rng(8)
    n = 800
    o = np.column_stack([rng.uniform(-20, 20, (n, 2)), np.full(n, p.vertex_z[-1] + 60.0)])
    tilt, az = np.radians(12.0) * np.sqrt(rng.random(n)), 2 * np.pi * rng.random(n)
    d = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)])
    ev = tracer.next_event(RayBatch.make(o, d, wavelength=np.zeros(n, np.int64)))
    gone = (ev.kind == GONE) & ~ev.lost
    assert gone.sum() > n // 10 and (ev.kind == FACE).sum() > n // 10
    mech = mesh.triangles[np.array([t.role != "optical" for t in mesh.tag_table])[mesh.tags]]
    t_hit, _ = reference_nearest(ev.position[gone], ev.direction[gone], mesh.vertices[mech])
    assert not np.isfinite(t_hit).any()


def _ghost_bundle(n=20_000, seed=4):
    """Rays at up to 6° over 1.2× the double Gauss's aperture: some reach the detector, some meet
    the barrel or the diaphragm, and the uncoated glass reflects some of them (ghosts on)."""
    from tests.trace.geometry import make_scene
    from lensmount.physics.rays import RayBatch
    from lensmount.trace.tracer import Tracer

    p = double_gauss()
    tracer = Tracer(make_scene(p, double_gauss_mesh(p, rings=6, segments=24), coatings={"default": "uncoated"},
                               effects={"scatter": True, "ghosts": True, "direct": True}))
    rng = np.random.default_rng(seed)
    r, phi = 30.0 * np.sqrt(rng.random(n)), 2 * np.pi * rng.random(n)
    tilt, az = np.radians(6.0) * rng.random(n), 2 * np.pi * rng.random(n)
    d = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    o = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n, -40.0)])
    return tracer, RayBatch.make(o, d, wavelength=np.zeros(n, np.int64)), Streams(3, "ghosts", np.arange(n))


def test_the_walk_on_all_cores_is_the_walk_on_one_core(monkeypatch):
    """A ray's walk reads and writes only its own rows: traced on every core, every event is the
    same bits as on one core (Fresnel branch on, so the ghost pairs and stream draws are compared too)."""
    tracer, rays, streams = _ghost_bundle()
    assert len(rays) >= lens_kernel.THREADED_FROM
    monkeypatch.setattr(lens_kernel, "_ONE_CORE", [False])
    threaded = tracer.next_event(rays, streams)
    monkeypatch.setattr(lens_kernel, "_ONE_CORE", [True])
    one_core = tracer.next_event(rays, streams)
    assert threaded.reflections.sum() > 100 and (threaded.kind == 1).sum() > 100  # ghosts and metal were walked
    for field in ("kind", "position", "direction", "normal", "tag", "prim", "pixel", "weight", "lost", "reflections",
                  "ghost_pair"):
        assert np.array_equal(getattr(threaded, field), getattr(one_core, field)), field


def test_a_forked_worker_traces_after_its_parent_walked_on_all_cores():
    """GNU OpenMP, numba's threading layer here, is not fork-safe: a child that starts threads its
    parent already started is killed. The executor's workers walk on one core, so a run whose driver
    traced first (the photon aiming's pilot does) still gets its passes back."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import sys
        sys.path.insert(0, %r)
        from types import SimpleNamespace
        from lensmount.run.executor import LocalProcesses
        from tests.trace.test_lens_kernel import _ghost_bundle

        def bundle(scene):
            return _ghost_bundle(seed=4)

        def pass_in_worker(scene, bundle, job):
            tracer, rays, streams = bundle
            return int((tracer.next_event(rays, streams).kind == 2).sum())

        if __name__ == "__main__":
            tracer, rays, streams = _ghost_bundle(seed=4)
            here = int((tracer.next_event(rays, streams).kind == 2).sum())  # threads started in the parent
            workers = LocalProcesses(2)
            workers.start(None, "__main__:bundle", "__main__:pass_in_worker")
            workers.submit(SimpleNamespace(index=0))
            done = []
            while not done:
                done = workers.next_done()
            workers.close()
            print(here, done[0][1])
    """) % str(Path(__file__).resolve().parents[2])
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    here, there = map(int, out.stdout.split())
    assert here == there > 0
