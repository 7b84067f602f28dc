"""The compare verdict on synthetic pass series: noise is not a regression, a real change is, and
"undecided" says how many photons would decide — checked by giving it those photons."""

import math

import numpy as np
import pytest

from lensmount.analysis.compare import (
    IMPROVEMENT, NO_REGRESSION, REGRESSION, UNDECIDED, Measurement, judge, parse_fraction)


def run(rng, true_value, pass_sd, passes, photons_per_pass=100_000, seconds_per_pass=1.0):
    """A run's Measurement from `passes` independent pass estimates (mean, batch-means std error)."""
    x = rng.normal(true_value, pass_sd, passes)
    return Measurement(float(x.mean()), float(x.std(ddof=1) / math.sqrt(passes)), 0.0, passes,
                       passes * photons_per_pass, passes * seconds_per_pass)


@pytest.mark.parametrize("passes", [4, 8, 32])
def test_noise_alone_is_not_a_regression(passes):
    # Same design, different seeds: the verdict is exit 0 in >= 98 of 100 at 99 %, and
    # over 2000 pairs the regression rate stays near its (1 - c)/2 = 0.5 % bound, also
    # with few passes (where a normal quantile instead of Student's t would give ~3 %).
    rng = np.random.default_rng(passes)
    verdicts = [judge(run(rng, 1e-3, 3e-4, passes), run(rng, 1e-3, 3e-4, passes), 0.0, 0.99).verdict
                for _ in range(2000)]
    rate = verdicts.count(REGRESSION) / len(verdicts)
    assert rate < 0.015, rate
    assert sum(v != REGRESSION for v in verdicts[:100]) >= 98


def test_interval_covers_the_true_change():
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(2000):
        v = judge(run(rng, 1.0, 0.2, 6), run(rng, 1.3, 0.2, 10), 0.05, 0.95)
        hits += v.low <= 0.3 <= v.high
    assert 0.93 <= hits / 2000 <= 0.97


def test_clear_changes_have_the_right_sign():
    rng = np.random.default_rng(3)
    worse = judge(run(rng, 1.0, 0.05, 16), run(rng, 1.5, 0.05, 16), 0.05, 0.99)
    better = judge(run(rng, 1.0, 0.05, 16), run(rng, 0.5, 0.05, 16), 0.05, 0.99)
    assert worse.verdict == REGRESSION and worse.change > 0 and worse.low > worse.threshold
    assert better.verdict == IMPROVEMENT and better.change < 0 and better.high < -better.threshold


def test_a_change_inside_the_tolerance_passes():
    rng = np.random.default_rng(4)
    v = judge(run(rng, 1.0, 0.01, 32), run(rng, 1.02, 0.01, 32), 0.10, 0.99)
    assert v.verdict == NO_REGRESSION and v.high <= v.threshold


def test_a_change_below_the_noise_is_undecided_and_the_photon_estimate_decides_it():
    # True change +20 % with a 5 % tolerance, pass noise 60 %: undecided with 8 passes.
    old = Measurement(1.0, 0.6 / math.sqrt(8), 0.0, 8, 800_000, 8.0)
    new = Measurement(1.2, 0.6 / math.sqrt(8), 0.0, 8, 800_000, 8.0)
    v = judge(old, new, 0.05, 0.99)
    assert v.verdict == UNDECIDED and v.more_photons > 0 and v.more_time_s > 0
    # Give both runs the photons it asks for (errors fall as 1/sqrt(photons)) and it decides.
    f = 1 + v.more_photons / (old.photons + new.photons)
    scaled = [Measurement(m.value, m.std_error / math.sqrt(f) * 0.999, 0.0, int(8 * f), 0, 0.0) for m in (old, new)]
    assert judge(*scaled, 0.05, 0.99).verdict == REGRESSION


def test_bias_bounds_widen_the_interval_and_can_make_photons_useless():
    old = Measurement(1.0, 0.001, 0.1, 32)
    new = Measurement(1.1, 0.001, 0.1, 32)
    v = judge(old, new, 0.05, 0.99)
    assert v.verdict == UNDECIDED and v.more_photons is None and "bias" in v.note
    assert v.high - v.low > 0.4  # the two bounds, on both sides


def test_one_pass_has_no_error_bar():
    v = judge(Measurement(1.0, None, 0.0, 1), Measurement(2.0, 0.1, 0.0, 8))
    assert v.verdict == UNDECIDED and math.isinf(v.low)


def test_no_signal_in_either_run_is_no_regression():
    v = judge(Measurement(0.0, 0.0, 0.0, 8), Measurement(0.0, 0.0, 0.0, 8))
    assert v.verdict == NO_REGRESSION and v.change == 0


@pytest.mark.parametrize("text,value", [("5%", 0.05), ("0.05", 0.05), ("99 %", 0.99), (" 1e-2 ", 0.01)])
def test_fractions(text, value):
    assert parse_fraction(text, "--tolerance") == pytest.approx(value)


def test_bad_fraction_names_the_field():
    with pytest.raises(ValueError, match="--confidence"):
        parse_fraction("lots", "--confidence")
