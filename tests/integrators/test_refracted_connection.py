"""The chain from a point in front of a lens to a point behind it, against a meridional hand trace."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.integrators.bidirectional import Bidirectional, gather_cores  # noqa: E402
from lensmount.integrators.forward import Forward  # noqa: E402
from lensmount.integrators.estimate import scattering_tags  # noqa: E402
from lensmount.integrators.photon_mapping.refracted_connection import (  # noqa: E402
    Chain, ThroughOptics, Vertices, connections_through_optics, solve_chain, walk_share)
from lensmount.integrators.scatter_aim import aperture_targets  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.physics.rays import RayBatch  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402
from lensmount.optics.profiles import Profile  # noqa: E402
from lensmount.physics.interfaces import Coating  # noqa: E402
from lensmount.scene.scene import OpticalSurface  # noqa: E402

N_GLASS = 1.5
R1, R2, THICK, SEMI = 50.0, -50.0, 5.0, 15.0


def _surface(z, radius, n_before, n_after):
    c = 0.0 if radius is None else 1.0 / radius
    zero = np.zeros(1)
    return OpticalSurface(0, z, Profile(curvature=c), SEMI, np.array([n_before]), np.array([n_after]),
                          Coating("perfect-ar"), zero, zero, SEMI, False)


def _hand_trace(theta, z1, z2, surfaces):
    """Height at z2 of the meridional ray leaving (y=0, z1) at angle theta to the axis: circles and
    Snell's law by angles, nothing shared with the code under test."""
    y, z, ang = 0.0, z1, theta
    for zv, radius, n1, n2 in surfaces:
        dy, dz = math.sin(ang), math.cos(ang)
        if radius is None:
            t = (zv - z) / dz
            y, z = y + t * dy, zv
            normal_ang = 0.0
        else:
            cz = zv + radius
            bz, by = z - cz, y
            b = by * dy + bz * dz
            disc = b * b - (by * by + bz * bz - radius * radius)
            t = -b - math.sqrt(disc) if radius > 0 else -b + math.sqrt(disc)
            y, z = y + t * dy, z + t * dz
            normal_ang = math.atan2(-y, cz - z) if radius > 0 else math.atan2(y, z - cz)
        incidence = ang - normal_ang
        ang = normal_ang + math.asin(n1 / n2 * math.sin(incidence))
    return y + (z2 - z) * math.tan(ang)


def _bisect(fn, target, lo, hi):
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if (fn(mid) - target) * (fn(lo) - target) <= 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("curved", [False, True], ids=["slab", "biconvex"])
@pytest.mark.parametrize("height", [3.0, 8.0, 14.0])
def test_chain_matches_a_meridional_hand_trace(curved, height):
    """Direction at y1 and |dω1/dA2| = sin θ / (ρ dρ/dθ) (y1 on the axis) from an angle-by-angle trace."""
    r1, r2 = (R1, R2) if curved else (None, None)
    hand = [(0.0, r1, 1.0, N_GLASS), (THICK, r2, N_GLASS, 1.0)]
    optical = [_surface(0.0, r1, 1.0, N_GLASS), _surface(THICK, r2, N_GLASS, 1.0)]
    z1, z2 = -40.0, 80.0
    rho = lambda th: _hand_trace(th, z1, z2, hand)  # noqa: E731
    theta = _bisect(rho, height, 1e-6, 0.35)
    h = 1e-6
    drho = (rho(theta + h) - rho(theta - h)) / (2 * h)
    expected = math.sin(theta) / (height * drho)

    phi = 0.7  # any azimuth: the system is coaxial
    y1 = np.array([[0.0, 0.0, z1]])
    y2 = np.array([[height * math.cos(phi), height * math.sin(phi), z2]])
    found = solve_chain(Chain.between(optical, z1, z2), y1, y2, np.array([[0.0, 0.0, -1.0]]), np.array([0]))
    assert found.ok[0]
    assert math.acos(found.direction[0, 2]) == pytest.approx(theta, abs=1e-8)
    assert math.atan2(found.direction[0, 1], found.direction[0, 0]) == pytest.approx(phi, abs=1e-8)
    assert found.d_omega_d_area[0] == pytest.approx(expected, rel=1e-5)


def test_without_glass_the_term_is_the_ordinary_one():
    """A plane of index 1 on both sides: cos θ2 / |y1 − y2|² on a tilted face, for off-axis points."""
    optical = [_surface(0.0, None, 1.0, 1.0)]
    rng = np.random.default_rng(3)
    y1 = np.column_stack([rng.uniform(-5, 5, 20), rng.uniform(-5, 5, 20), np.full(20, -30.0)])
    y2 = np.column_stack([rng.uniform(-10, 10, 20), rng.uniform(-10, 10, 20), rng.uniform(20, 60, 20)])
    n2 = np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0])
    normal = np.tile(n2, (20, 1))
    found = solve_chain(Chain.between(optical, -30.0, 100.0), y1, y2, normal, np.zeros(20, int))
    d = y2 - y1
    dist2 = np.einsum("ij,ij->i", d, d)
    cos2 = np.abs(d @ n2) / np.sqrt(dist2)
    assert found.ok.all()
    np.testing.assert_allclose(found.direction, d / np.sqrt(dist2)[:, None], atol=1e-9)
    np.testing.assert_allclose(found.d_omega_d_area, cos2 / dist2, rtol=1e-6)


def test_a_point_outside_the_lens_reach_is_refused():
    """y2 far beyond what the lens's aperture can send there from y1: no chain, nothing counted."""
    optical = [_surface(0.0, R1, 1.0, N_GLASS), _surface(THICK, R2, N_GLASS, 1.0)]
    found = solve_chain(Chain.between(optical, -40.0, 80.0), np.array([[0.0, 0.0, -40.0]]),
                        np.array([[0.0, 400.0, 80.0]]), np.array([[0.0, 0.0, -1.0]]), np.array([0]))
    assert not found.ok[0]
    assert found.d_omega_d_area[0] == 0.0


def _barrel_vertices(scene, tracer, n=400, seed=5):
    """n scatters on the barrel's bore in front of the singlet, lit from the front at random."""
    rng = np.random.default_rng(seed)
    phi = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(-25.0, -3.0, n)
    out = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(n)])
    hit = tracer.intersect(RayBatch.make(np.column_stack([np.zeros((n, 2)), z]), out))
    normal = -out  # the bore faces the axis
    wi = np.column_stack([-out[:, :2] * 0.5, np.full(n, -1.0)])
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    return Vertices(hit.point, wi, normal, hit.tag.astype(np.int64), np.ones(n), np.zeros(n, np.int64),
                    np.arange(n, dtype=np.int64))


def _through_optics(scene):
    core = gather_cores(scene.bsdf_of_tag)
    scatters = scattering_tags(scene)
    aim = aperture_targets(scene).only((core == 0) & scatters)
    return ThroughOptics.of_scene(scene, core, scatters, aim)


def test_a_path_sampled_both_ways_has_weights_summing_to_one():
    """Every connection that lands, seen as the walk's photon from y1 to y2 along the same chain: the two
    balance-heuristic weights add to 1, and both techniques have a share of it."""
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.5), off_axis_deg=25.0, pixels=(8, 8))
    tracer = Tracer(scene)
    optics = _through_optics(scene)
    v = _barrel_vertices(scene, tracer)
    assert optics.starts(v.tag, v.position).all()
    a = connections_through_optics(scene, tracer, optics.cells, optics.aim, v, 1, 7, "test")
    assert len(a.rows) > 20
    walk = walk_share(scene, optics.cells, optics.aim, v.take(a.rows), a.position, a.direction, a.normal, a.prim)
    np.testing.assert_allclose(a.share + walk, 1.0, atol=1e-9)
    assert (a.share > 0).all() and (walk > 0).all()


@pytest.mark.slow
def test_bidirectional_with_the_connection_through_the_optics_reads_what_the_forward_walk_reads():
    """A singlet's barrel at 30°, past its field: light scatters on the bore in front of the lens, crosses it and
    scatters again on the bore the detector sees. With the connection through the optics on (and carrying part
    of that light), the bidirectional estimator and the plain forward walk agree within 3.5 σ."""
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.5), off_axis_deg=30.0, pixels=(8, 8))
    tracer = Tracer(scene)
    assert _through_optics(scene) is not None
    on = Bidirectional(EstimatorSettings(connect_through_optics=True))
    bidir = np.array([on.run_pass(scene, tracer, i, 8_000, 4).flux for i in range(10)])
    fwd = np.array([Forward().run_pass(scene, tracer, i, 60_000, 4).flux for i in range(10)])
    a, sa = bidir.mean(), bidir.std(ddof=1) / math.sqrt(len(bidir))
    b, sb = fwd.mean(), fwd.std(ddof=1) / math.sqrt(len(fwd))
    assert a > 0 and b > 0
    assert abs(a - b) < 3.5 * math.hypot(sa, sb), (a, sa, b, sb)
