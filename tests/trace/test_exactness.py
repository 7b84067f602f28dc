"""The tracer is exact at close faces and knife edges.

- A ray leaving glass finds metal beyond it however close: glass-to-metal gaps from 0 to 5 µm,
  flat and curved glass, at normal and oblique exit.
- Rays aimed at a 50 µm land from both sides hit it exactly when an exact float64 intersection
  of the same ray with the same triangles says so. The reference below is this test's own
  vectorised Möller–Trumbore (numpy, float64), written independently of the tracer.
"""

import math

import numpy as np
import pytest

from tests.trace.geometry import make_scene, mech_scene, window
from lensmount.mesh import TaggedMesh
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.scene import primitives
from lensmount.physics.rays import RayBatch
from lensmount.trace.tracer import FACE, Tracer

GAPS_UM = [0.0, 0.01, 0.1, 0.3, 0.5, 0.9, 1.0, 1.2, 1.5, 2.0, 2.4, 3.0, 5.0]


def reference_nearest(o, d, tri, chunk=2000):
    """Nearest float64 crossing of rays (n, 3) with triangles (k, 3, 3): (t (n,), index (n,) or -1)."""
    a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    t_best = np.full(len(o), np.inf)
    i_best = np.full(len(o), -1)
    for s in range(0, len(o), chunk):
        oo, dd = o[s:s + chunk, None, :], d[s:s + chunk, None, :]
        p = np.cross(dd, e2[None])
        det = np.sum(e1[None] * p, axis=2)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = oo - a[None]
            u = np.sum(tv * p, axis=2) * inv
            q = np.cross(tv, e1[None])
            v = np.sum(dd * q, axis=2) * inv
            t = np.sum(e2[None] * q, axis=2) * inv
        hit = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        t = np.where(hit, t, np.inf)
        k = np.argmin(t, axis=1)
        t_best[s:s + chunk] = t[np.arange(len(k)), k]
        i_best[s:s + chunk] = np.where(np.isfinite(t_best[s:s + chunk]), k, -1)
    return t_best, i_best


def _glass_and_shoulder(p, gap_mm, r0, z_face):
    """Glass of prescription p and a metal block whose face (facing the glass, −z) lies gap_mm
    beyond z_face around radius r0."""
    glass = primitives.lens_elements(p, [20.0] * len(p.surfaces), rings=8, segments=48)
    metal = primitives.box((r0 - 3.0, -3.0, z_face + gap_mm), (r0 + 3.0, 3.0, z_face + gap_mm + 2.0),
                           part="barrel", kind="barrel")
    return make_scene(p, TaggedMesh.concatenate([glass, metal]),
                      detector={"width_mm": 10, "height_mm": 10, "pixels": [1, 1], "z_mm": 500.0})


@pytest.mark.parametrize("curved", [False, True])
def test_ray_leaving_glass_finds_metal_at_any_gap(curved):
    if curved:  # a biconvex singlet: its rear face is a coarse chord polygon (µm from the sphere)
        p = Prescription((Surface(radius=80.0, thickness=6.0, material="SCHOTT:N-BK7", clear_semi_diameter=20.0,
                                  mechanical_semi_diameter=20.0),
                          Surface(radius=-80.0, thickness=50.0, clear_semi_diameter=20.0,
                                  mechanical_semi_diameter=20.0)), Aperture("epd", 30.0))
    else:
        p = window()
    r0 = 16.0
    from lensmount.optics.profiles import Profile
    z_rear = p.vertex_z[1] + Profile.of(p.surfaces[1]).sag(np.array([r0 * r0]))[0]
    for gap_um in GAPS_UM:
        scene = _glass_and_shoulder(p, gap_um * 1e-3, r0, z_rear)
        tracer = Tracer(scene)
        barrel = [k for k, t in enumerate(scene.mesh.tag_table) if t.part == "barrel"]
        # Rays inside the glass crossing the rear face at r0 (and around it), straight and oblique.
        tilt = np.radians([0.0, 3.0, -7.0, 12.0, 20.0])
        target = np.array([[r0 + dx, dy, z_rear] for dx in (-0.5, 0.0, 0.37) for dy in (-0.2, 0.0, 0.31)])
        o, d = [], []
        for a in tilt:
            dd = np.array([math.sin(a), 0.3 * math.sin(a), math.cos(a)])
            dd /= np.linalg.norm(dd)
            for tg in target:
                o.append(tg - 1.0 * dd)
                d.append(dd)
        ev = tracer.next_event(RayBatch.make(np.array(o), np.array(d)))
        assert np.all(ev.kind == FACE), f"gap {gap_um} µm: a ray left the glass and missed the metal"
        assert np.all(np.isin(ev.tag, barrel)), f"gap {gap_um} µm"
        # The hit lies on the metal's face, a gap beyond the glass, not inside the block.
        np.testing.assert_allclose(ev.position[:, 2], z_rear + gap_um * 1e-3, atol=1e-9)


def _land_rays(r_land, z0, z1, n, side, rng, phi_range):
    """Rays aimed at points on the cylinder r = r_land (z0 − 30 µm .. z1 + 30 µm) from inside the
    aperture, travelling +z (sun side) or −z (detector side), starting 2 mm before the aim."""
    phi = rng.uniform(*phi_range, n)
    z = rng.uniform(z0 - 0.03, z1 + 0.03, n)
    aim = np.column_stack([r_land * np.cos(phi), r_land * np.sin(phi), z])
    alpha = np.radians(rng.uniform(5.0, 85.0, n))  # angle from the axis
    swing = phi + np.radians(rng.uniform(-60.0, 60.0, n))  # azimuth of travel, outward-ish
    d = np.column_stack([np.sin(alpha) * np.cos(swing), np.sin(alpha) * np.sin(swing), side * np.cos(alpha)])
    return aim - 2.0 * d, d


def _agree_on_land(tracer, mesh, land, o, d):
    hits = tracer.intersect(RayBatch.make(o, d))
    lo = np.minimum(o, o + 3.0 * d).min(axis=0) - 0.1
    hi = np.maximum(o, o + 3.0 * d).max(axis=0) + 0.1
    tri = mesh.vertices[mesh.triangles]
    near = np.flatnonzero(np.all(tri.max(axis=1) >= lo, axis=1) & np.all(tri.min(axis=1) <= hi, axis=1))
    t_ref, k = reference_nearest(o, d, tri[near])
    ref_prim = np.where(k >= 0, near[np.maximum(k, 0)], -1)
    ref_land = (ref_prim >= 0) & land[np.maximum(ref_prim, 0)] & (t_ref < 3.0)
    got_land = (hits.prim >= 0) & land[np.maximum(hits.prim, 0)]
    bad = np.flatnonzero(ref_land != got_land)
    assert bad.size == 0, (f"{bad.size} of {len(o)} rays disagree with float64 on the land: "
                           f"tracer {got_land[bad[:5]]}, reference {ref_land[bad[:5]]}")
    assert 0.2 < ref_land.mean() < 0.8  # the aim straddles the land: both outcomes are tested
    both = ref_land
    np.testing.assert_allclose(hits.t[both], t_ref[both], rtol=0, atol=1e-9)
    return ref_land.sum()


def test_50um_land_from_both_sides_agrees_with_float64():
    """A diaphragm with a 50 µm land (240 sides) in a barrel: 2 × 50 000 rays."""
    r_land, z0, z1 = 17.0, 100.0, 100.05
    dia = primitives.tube(z0, z1, r_land, 30.0, part="diaphragm", kind="diaphragm", segments=240)
    barrel = primitives.tube(0.0, 200.0, 30.0, 33.0)
    mesh = TaggedMesh.concatenate([dia, barrel])
    tracer = Tracer(mech_scene(mesh, detector={"width_mm": 1, "height_mm": 1, "pixels": [1, 1], "z_mm": 5000.0}))
    r = np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1])
    land = np.all(np.isclose(r[mesh.triangles], r_land), axis=1)
    rng = np.random.default_rng(8)
    for side in (1.0, -1.0):
        o, d = _land_rays(r_land * math.cos(math.pi / 240), z0, z1, 50_000, side, rng, (0.3, 0.5))
        _agree_on_land(tracer, mesh, land, o, d)


@pytest.mark.slow
def test_reference_design_land_from_both_sides_agrees_with_float64(tmp_path_factory):
    """The reference design's diaphragm edge (regenerated CAD): 2 × 100 000 rays."""
    pytest.importorskip("build123d")
    from pathlib import Path

    from lensmount.cad.pipeline import regenerate
    from lensmount.design.lens import load_lens
    from lensmount.design.scene import scene_from_dict
    from lensmount.scene.build import build_scene
    from tests.trace.geometry import scene_dict

    design = Path(__file__).resolve().parents[2] / "src" / "lensmount" / "examples" / "double-gauss-360"
    out = tmp_path_factory.mktemp("dg360")
    mesh = TaggedMesh.load(out / regenerate(design, out).mesh)
    scene = build_scene(load_lens(design / "lens.toml"), mesh, scene_from_dict(scene_dict()))
    tracer = Tracer(scene)
    land_tags = [k for k, t in enumerate(mesh.tag_table) if t.role == "diaphragm-edge"]
    land = np.isin(mesh.tags, land_tags)
    v = mesh.vertices[mesh.triangles[land]].reshape(-1, 3)
    r = np.hypot(v[:, 0], v[:, 1])
    z0, z1 = v[:, 2].min(), v[:, 2].max()
    assert 0.045 < z1 - z0 < 0.055
    rng = np.random.default_rng(13)
    for side in (1.0, -1.0):
        # Aim at the chord polygon's face centres' radius so the aims straddle the facets.
        o, d = _land_rays(0.5 * (r.min() + r.max()), z0, z1, 100_000, side, rng, (0.3, 0.5))
        _agree_on_land(tracer, mesh, land, o, d)
