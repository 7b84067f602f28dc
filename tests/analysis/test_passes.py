"""Accumulator: batch-means statistics against numpy on known series, checkpoint round trip."""

import math

import numpy as np
import pytest

from scipy.stats import norm
from scipy.stats import t as student_t

from lensmount.analysis.passes import Accumulator
from lensmount.integrators.estimate import PassEstimate


def _pass(rng, scale=1.0, shape=(4, 5)):
    img = rng.exponential(scale, size=shape)
    parts = np.stack([0.25 * img, 0.75 * img])
    return PassEstimate(img, parts, ["diaphragm", "barrel"], pixel_area_mm2=0.01, photons=100)


def test_mean_and_std_error_match_numpy():
    rng = np.random.default_rng(1)
    passes = [_pass(rng) for _ in range(40)]
    acc = Accumulator.empty((4, 5), ["diaphragm", "barrel"], 0.01)
    for p in passes:
        acc.add(p)
    stack = np.stack([p.image for p in passes])
    np.testing.assert_allclose(acc.mean_image, stack.mean(0), rtol=1e-12)
    widen = student_t.ppf(0.975, 39) / norm.ppf(0.975)  # Student-t at 39 degrees of freedom
    np.testing.assert_allclose(acc.std_error_image, stack.std(0, ddof=1) / math.sqrt(40) * widen, rtol=1e-9)
    flux = stack.sum(axis=(1, 2)) * 0.01
    assert acc.flux == pytest.approx(flux.mean(), rel=1e-12)
    assert acc.flux_std_error == pytest.approx(flux.std(ddof=1) / math.sqrt(40) * widen, rel=1e-9)
    np.testing.assert_allclose(acc.part_flux, [0.25 * flux.mean(), 0.75 * flux.mean()], rtol=1e-12)
    assert acc.photons == 4000 and acc.n == 40 and acc.last_pass == 39


def test_std_error_covers_the_truth_at_the_nominal_rate():
    """Over many independent runs, |mean − truth| < 2 SE about 95 % of the time."""
    rng = np.random.default_rng(7)
    inside = 0
    for _ in range(200):
        acc = Accumulator.empty((1, 1), ["p"], 1.0)
        for _ in range(30):
            v = rng.exponential(1.0, size=(1, 1))
            acc.add(PassEstimate(v, v[None], ["p"], 1.0, 1))
        inside += abs(acc.flux - 1.0) < 2 * acc.flux_std_error
    assert 0.88 < inside / 200 < 0.99


def test_few_normal_passes_cover_the_truth_at_the_nominal_rate():
    """With 4 passes the plain standard error covers only 88 % at ±2 SE (t with 3
    degrees of freedom); the Student-t widened one covers 95 %."""
    rng = np.random.default_rng(17)
    trials, inside = 3000, 0
    for _ in range(trials):
        acc = Accumulator.empty((1, 1), ["p"], 1.0)
        for v in rng.normal(1.0, 0.2, 4):
            acc.add(PassEstimate(np.array([[v]]), np.array([[[v]]]), ["p"], 1.0, 1))
        inside += abs(acc.flux - 1.0) < 1.96 * acc.flux_std_error
    assert 0.935 < inside / trials < 0.965, inside / trials


def test_no_error_bar_from_two_passes():
    acc = Accumulator.empty((1, 1), ["p"], 1.0)
    for v in (1.0, 1.1):
        acc.add(PassEstimate(np.array([[v]]), np.array([[[v]]]), ["p"], 1.0, 1))
    assert acc.flux_std_error == math.inf and acc.rel_error() == math.inf
    acc.add(PassEstimate(np.array([[0.9]]), np.array([[[0.9]]]), ["p"], 1.0, 1))
    assert math.isfinite(acc.flux_std_error) and acc.rel_error() < 1


def test_no_signal_is_never_converged_and_has_an_upper_bound():
    """All-zero passes are no error bar of 0 ± 0 (a stopping rule on that would stop): the relative
    error is unknown and the 95 % bound is 3 photons' worth of
    the emitted flux over the run's 8000 photons (the ledger's `source`, 5 mm² per pass of 1000
    photons here): no photon in 8000 means a chance below 3/8000 per photon, so the mean pass
    flux is below 5 · 3/8000 (not 5 · 3/1000, the bound of one pass: 8× loose)."""
    acc = Accumulator.empty((2, 2), ["p"], 1.0)
    assert acc.rel_error() == math.inf and acc.flux == 0.0 and acc.upper_bound() is None
    assert np.all(acc.std_error_image == 0) and np.all(np.isfinite(acc.mean_image))
    z = np.zeros((2, 2))
    for _ in range(8):
        acc.add(PassEstimate(z, z[None], ["p"], 1.0, 1000, ledger={"source": 5.0, "escaped": 5.0}))
    assert acc.rel_error() == math.inf
    assert acc.upper_bound() == pytest.approx(3.0 * 5.0 / 8000)  # Φ per photon = 5/1000, < 3 photons in 8000
    d = acc.drift()
    assert d.relative == 0.0 and d.z == 0.0
    one = np.array([[0.0, 1e-9], [0.0, 0.0]])
    acc.add(PassEstimate(one, one[None], ["p"], 1.0, 1000, ledger={"source": 5.0}))
    assert acc.upper_bound() is None


def test_no_signal_bound_of_aimed_photons_takes_the_heaviest_weight():
    """Photons aimed at the diaphragm edge weigh up to A_S / (N · UNIFORM_SHARE)
    (the disc's uniform share, 5× the mean weight); the bound must take that weight, not the mean.
    Checked against Poisson directly: photons of weight 5w hitting with probability p give the mean
    flux 5w·p·N per pass, and the bound must lie above it whenever all-zero runs are common (p·N·n = 3)."""
    from lensmount.integrators.estimate import AIMED_PASSES
    from lensmount.integrators.photon_mapping.photon_target import UNIFORM_SHARE

    acc = Accumulator.empty((1, 1), ["p"], 1.0)
    z = np.zeros((1, 1))
    for _ in range(4):
        acc.add(PassEstimate(z, z[None], ["p"], 1.0, 1000, ledger={"source": 5.0}, diagnostics={AIMED_PASSES: 1.0}))
    heaviest = 5.0 / 1000 / UNIFORM_SHARE
    p = 3.0 / 4000  # chance per photon at which 4 × 1000 photons all miss 5 % of the time
    assert math.exp(-p * 4000) == pytest.approx(0.05, rel=0.01)
    assert acc.upper_bound() == pytest.approx(heaviest * p * 1000)  # the true mean flux at that chance


def test_nan_pass_is_refused():
    acc = Accumulator.empty((1, 2), ["p"], 1.0)
    bad = np.array([[1.0, np.nan]])
    with pytest.raises(ValueError):
        acc.add(PassEstimate(bad, bad[None], ["p"], 1.0, 1))


def test_drift_detects_a_trend_and_not_noise():
    rng = np.random.default_rng(3)
    flat = Accumulator.empty((1, 1), ["p"], 1.0)
    trend = Accumulator.empty((1, 1), ["p"], 1.0)
    for i in range(64):
        v = 1.0 + 0.01 * rng.standard_normal((1, 1))
        flat.add(PassEstimate(v, v[None], ["p"], 1.0, 1))
        w = v + 0.002 * i
        trend.add(PassEstimate(w, w[None], ["p"], 1.0, 1))
    assert abs(flat.drift().z) < 4
    assert trend.drift().z > 10 and trend.drift().relative > 0


def test_checkpoint_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(5)
    acc = Accumulator.empty((4, 5), ["diaphragm", "barrel"], 0.01)
    for i in range(5):
        acc.add(_pass(rng), pass_index=i)
    path = tmp_path / "checkpoint.npz"
    acc.save(path, seed=3, input_hash="abc", method="bidirectional")
    back, meta = Accumulator.load(path)
    assert meta == {"seed": 3, "input_hash": "abc", "method": "bidirectional"}
    assert back.n == 5 and back.last_pass == 4 and back.part_names == acc.part_names
    np.testing.assert_array_equal(back.sum_image, acc.sum_image)
    assert back.flux_std_error == acc.flux_std_error
    # Continuing from the checkpoint equals never stopping.
    p = _pass(rng)
    acc.add(p, 5)
    back.add(p, 5)
    assert back.flux == acc.flux and back.flux_std_error == acc.flux_std_error
    assert back.bias_bound()[0] == acc.bias_bound()[0]
    assert not list(tmp_path.glob("*.tmp"))


def test_drift_p_value_is_calibrated_for_few_identical_passes():
    """Review finding: with 4 to 8 independent identical passes |z| > 2 far more often than 5 %;
    the Welch p-value keeps false alarms near its nominal rate."""
    rng = np.random.default_rng(11)
    for n in (4, 8):
        alarms = 0
        trials = 400
        for _ in range(trials):
            acc = Accumulator.empty((1, 1), ["a"], 1.0)
            for value in rng.normal(1.0, 0.1, n):
                acc.add(PassEstimate(np.array([[value]]), np.array([[[value]]]), ["a"], 1.0, 1))
            alarms += acc.drift().p < 0.05
        assert alarms / trials < 0.09, (n, alarms / trials)
