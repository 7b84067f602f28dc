"""Backward sampler toward the exit disc: unbiased for any D and c (analytic integrals)."""

import math

import numpy as np
import pytest

from lensmount.integrators.exit_sampler import ExitDisc, sample_toward_exit


def _estimate(radiance, disc, c, n=400_000, seed=0):
    rng = np.random.default_rng(seed)
    x = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), np.full(n, 100.0)])
    omega, w = sample_toward_exit(x, rng.random((n, 3)), disc, c)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    v = w * radiance(x, omega)
    return v.mean(), v.std() / math.sqrt(n)


def _cone(beta):
    """L = 1 inside a cone of half-angle beta about −z: ∫ L cos dω = π sin² β."""
    return lambda x, om: (-om[:, 2] > math.cos(beta)).astype(float)


@pytest.mark.parametrize("radius,c", [(10.0, 0.9), (20.0, 0.9), (10.0, 0.5), (10.0, 0.0), (40.0, 1.0)])
def test_cone_irradiance_any_disc_any_mixture(radius, c):
    beta = math.radians(4.0)
    disc = ExitDisc(z=0.0, radius=radius)  # 100 mm in front of the detector
    if c == 1.0:  # the disc alone is unbiased only if it covers the whole cone
        assert radius > 100 * math.tan(beta) + 1.5
    mean, se = _estimate(_cone(beta), disc, c)
    expected = math.pi * math.sin(beta) ** 2
    assert abs(mean - expected) < 4 * se + 1e-12


def test_full_hemisphere_gives_pi():
    mean, se = _estimate(lambda x, om: np.ones(len(x)), ExitDisc(0.0, 10.0), 0.8)
    assert abs(mean - math.pi) < 4 * se


def test_disc_concentrates_samples_on_the_lens():
    """Variance reduction is the point of D: with c = 0.9 the cone estimate is far less noisy."""
    beta = math.radians(4.0)
    _, se_mix = _estimate(_cone(beta), ExitDisc(0.0, 10.0), 0.9, n=100_000)
    _, se_hemi = _estimate(_cone(beta), ExitDisc(0.0, 10.0), 0.0, n=100_000)
    assert se_mix < se_hemi / 5


def test_disc_plus_rim_annulus_mixture_is_unbiased():
    beta = math.radians(4.0)
    disc = ExitDisc(0.0, 10.0)
    rim = ExitDisc(20.0, 6.2, r_inner=5.8)
    rng = np.random.default_rng(4)
    n = 400_000
    x = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), np.full(n, 100.0)])
    omega, w = sample_toward_exit(x, rng.random((n, 3)), [disc, rim], [0.5, 0.4])
    v = w * _cone(beta)(x, omega)
    assert abs(v.mean() - math.pi * math.sin(beta) ** 2) < 4 * v.std() / math.sqrt(n)


def test_weights_summing_above_one_are_refused():
    with pytest.raises(ValueError):
        sample_toward_exit(np.zeros((2, 3)), np.zeros((2, 3)), [ExitDisc(0, 1), ExitDisc(0, 2)], [0.6, 0.6])
