"""Photons' scatter aimed at the next clear aperture (`integrators.scatter_aim`): the mixture keeps every
integral of the BSDF (closed forms), sends more directions through the disc, and the targets follow the lens."""

import dataclasses
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import double_gauss_case, singlet_barrel  # noqa: E402

from lensmount.integrators.exit_sampler import ExitDisc  # noqa: E402
from lensmount.integrators.forward import Forward  # noqa: E402
from lensmount.integrators.bidirectional import Bidirectional  # noqa: E402
from lensmount.integrators.scatter_aim import AIMED_SHARE, ApertureTargets, aperture_targets  # noqa: E402
from lensmount.integrators.walk import NonFiniteError  # noqa: E402
from lensmount.integrators.walk import _scatter as walk_scatter  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.physics.sampler import Streams  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402

M = 400_000
FACE = SimpleNamespace(part="barrel", role="mount", finish="test")


def _scatter(bsdf, normal, wi, h=10.0, radius=4.0, seed=3):
    """M photons at the origin on a face with `normal`, aimed at a disc of `radius` at z = h on the axis."""
    scene = SimpleNamespace(bsdf_of_tag=[bsdf], mesh=SimpleNamespace(tag_table=[FACE]))
    targets = ApertureTargets((ExitDisc(z=h, radius=radius, facing=1.0),), np.array([True]))
    rows = np.arange(M)
    n = np.tile(np.asarray(normal, float) / np.linalg.norm(normal), (M, 1))
    wi = np.tile(np.asarray(wi, float) / np.linalg.norm(wi), (M, 1))
    position = np.zeros((M, 3))
    assert targets.aimed(np.zeros(M, np.int64), position).all()
    wo, w = walk_scatter(scene, np.zeros(M, np.int64), position, wi, n, Streams(seed, "test-aim", rows), rows, targets)
    t = h / np.where(wo[:, 2] > 0, wo[:, 2], np.inf)
    through = (wo[:, 2] > 0) & (np.hypot(wo[:, 0] * t, wo[:, 1] * t) <= radius)
    return wo, w, through


def _mean_and_error(v):
    return v.mean(), v.std(ddof=1) / math.sqrt(len(v))


@pytest.mark.parametrize("tilt_deg", [0.0, 60.0])
def test_the_aimed_mixture_keeps_the_albedo(tilt_deg):
    """E[f cos θ / p] over the mixture = ∫ f cos θ dω = ρ, also when the face is tilted so far that part of the
    disc lies below it (those aimed directions carry nothing; the BSDF half still covers the hemisphere)."""
    t = math.radians(tilt_deg)
    _, w, _ = _scatter(make_bsdf("lambertian", reflectance=0.3), (math.sin(t), 0.0, math.cos(t)), (0.2, 0.1, 1.0))
    mean, se = _mean_and_error(w)
    assert abs(mean - 0.3) < 4 * se + 1e-12, (mean, se)
    assert np.all(np.isfinite(w)) and w.max() <= 0.3 / (1 - AIMED_SHARE) + 1e-12  # at most 1/(1 − c) of ρ


def test_the_light_through_the_disc_is_the_lambertian_integral_and_more_samples_carry_it():
    """Through a disc of radius R at height h on the normal: ∫ ρ/π cos θ dω = ρ R² / (h² + R²) (closed form).
    The aimed photons find it with at least c of their directions, against R²/(h² + R²) = 14 % unaimed."""
    h, radius, rho = 10.0, 4.0, 0.3
    _, w, through = _scatter(make_bsdf("lambertian", reflectance=rho), (0, 0, 1), (0.2, 0.1, 1.0), h, radius)
    mean, se = _mean_and_error(w * through)
    exact = rho * radius ** 2 / (h ** 2 + radius ** 2)
    assert abs(mean - exact) < 4 * se, (mean, se, exact)
    assert through.mean() > AIMED_SHARE
    # the same integral from the unaimed photons has a larger error than the aimed ones (what aiming is for)
    assert se < 0.5 * rho * math.sqrt(exact / rho * (1 - exact / rho) / M)


def test_a_broad_abg_lobe_keeps_its_moments():
    """A finish that is not Lambertian (a wide ABg lobe the gather counts whole): E[w ω_x²] and E[w] under the
    mixture equal those under the BSDF's own sampling (independent numbers, same integrals)."""
    bsdf = make_bsdf("abg", A=0.02, B=0.2, g=1.5)
    normal, wi = (0.0, 0.0, 1.0), (0.5, 0.0, 1.0)
    wo, w, _ = _scatter(bsdf, normal, wi)
    n = np.tile([0.0, 0.0, 1.0], (M, 1))
    wi_rows = np.tile(np.asarray(wi) / np.linalg.norm(wi), (M, 1))
    u = np.random.default_rng(11).random((M, 2))
    wo_ref, w_ref, _ = bsdf.sample(wi_rows, n, u)
    for g in (lambda d: np.ones(len(d)), lambda d: d[:, 0] ** 2, lambda d: np.maximum(d[:, 0], 0.0)):
        a, sa = _mean_and_error(w * g(wo))
        b, sb = _mean_and_error(np.asarray(w_ref) * g(wo_ref))
        assert abs(a - b) < 4 * math.hypot(sa, sb), (a, sa, b, sb)


def test_the_targets_follow_the_lens():
    """Double Gauss: a disc per surface in front of its whole surface; a point is aimed at the first disc
    beyond it; behind the last surface nothing is; glass faces are never aimed; a mirror turns aiming off."""
    scene = double_gauss_case(2)
    targets = aperture_targets(scene)
    assert targets is not None and len(targets.discs) == len(scene.optical)
    planes = targets.planes
    assert np.all(np.diff(planes) > 0)
    vertex = np.sort([s.z_vertex for s in scene.optical])
    assert np.all(planes <= vertex + 1e-9)
    between = 0.5 * (vertex[3] + vertex[4])
    z = np.array([vertex[0] - 20.0, between, vertex[-1] + 5.0])
    points = np.column_stack([np.full(3, 30.0), np.zeros(3), z])
    assert list(targets.disc_of(points)[:2]) == [0, int(np.searchsorted(planes, between, side="right"))]
    mechanical = np.flatnonzero(targets.faces)
    assert len(mechanical) and not targets.aimed(np.array([mechanical[0]]), points[2:]).any()
    glass = np.flatnonzero(np.any(np.asarray(scene.solid_index_of_tag) != 1.0, axis=1))
    assert not targets.faces[glass].any()
    folded = dataclasses.replace(scene, optical=[dataclasses.replace(scene.optical[0], mirror=True)]
                                 + list(scene.optical[1:]))
    assert aperture_targets(folded) is None


@pytest.mark.slow
def test_aimed_bidirectional_reads_what_the_forward_walk_reads_past_the_field():
    """A singlet's barrel lit at 25°, far past its field: the light reaches the detector only after a scatter in
    front of the lens that crosses it (aimed) and a second one on the barrel behind it. The bidirectional
    estimator (aimed photons, gather, connections) and the forward walk (no aiming) agree within 3.5 σ."""
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.5), off_axis_deg=25.0, pixels=(8, 8))
    tracer = Tracer(scene)
    assert aperture_targets(scene) is not None
    bidir = np.array([Bidirectional().run_pass(scene, tracer, i, 10_000, 9).flux for i in range(10)])  # ~3 %
    fwd = np.array([Forward().run_pass(scene, tracer, i, 60_000, 9).flux for i in range(10)])  # ~2.5 %
    (a, sa), (b, sb) = _mean_and_error(bidir), _mean_and_error(fwd)
    assert a > 0 and b > 0
    assert abs(a - b) < 3.5 * math.hypot(sa, sb), (a, sa, b, sb)


def test_a_finish_whose_value_is_not_finite_is_named_not_zeroed():
    """A BSDF that returns NaN on an aimed face: the walk stops with the finish's name (never a silent 0)."""
    class Broken:
        def sample(self, wi, n, u):
            return n.copy(), np.ones(len(n)), np.ones(len(n))

        def eval(self, wi, wo, n):
            return np.full(len(n), np.nan)

        def pdf(self, wi, wo, n):
            return np.ones(len(n))

    tags = [SimpleNamespace(part="barrel", role="mount", finish="broken")]
    scene = SimpleNamespace(bsdf_of_tag=[Broken()], mesh=SimpleNamespace(tag_table=tags))
    targets = ApertureTargets((ExitDisc(z=10.0, radius=4.0, facing=1.0),), np.array([True]))
    rows = np.arange(8)
    n = np.tile([0.0, 0.0, 1.0], (8, 1))
    with pytest.raises(NonFiniteError, match="broken"):
        walk_scatter(scene, np.zeros(8, np.int64), np.zeros((8, 3)), n, n, Streams(1, "t", rows), rows, targets)
