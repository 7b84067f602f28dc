"""The compare verdict on synthetic pass series: noise is not a regression, a real change is, and
"undecided" says how many photons would decide — checked by giving it those photons.

The runs carry standard errors as the summaries give them: Student-t widened for their own passes
(`analysis.error_bar.t_factor`). Fed plain ones, these tests never saw compare widen a second time
(widened twice, a nominal 99 % interval covered 99.95 %)."""

import math
from pathlib import Path

import numpy as np
import pytest

from lensmount.analysis.compare import (
    IMPROVEMENT, NO_REGRESSION, REGRESSION, UNDECIDED, Measurement, interval, judge, parse_fraction, to_decide)
from lensmount.analysis.error_bar import t_factor


def of_passes(x, photons_per_pass=100_000, seconds_per_pass=1.0, no_signal_bound=None) -> Measurement:
    """A run's Measurement from its pass estimates, as `analysis.summary` reports it (mean, and the
    batch-means standard error × t_factor)."""
    n = len(x)
    return Measurement(float(np.mean(x)), float(np.std(x, ddof=1) / math.sqrt(n) * t_factor(n)), 0.0, n,
                       n * photons_per_pass, n * seconds_per_pass, no_signal_bound)


def run(rng, true_value, pass_sd, passes, photons_per_pass=100_000, seconds_per_pass=1.0):
    """A run of `passes` independent normal pass estimates."""
    return of_passes(rng.normal(true_value, pass_sd, passes), photons_per_pass, seconds_per_pass)


@pytest.mark.parametrize("passes", [4, 8, 32])
def test_noise_alone_is_not_a_regression(passes):
    # Same design, different seeds: the verdict is exit 0 in >= 98 of 100 at 99 %, and
    # over 1000 pairs the regression rate stays near its (1 - c)/2 = 0.5 % bound, also
    # with few passes (where a normal quantile instead of Student's t would give ~3 %).
    rng = np.random.default_rng(passes)
    verdicts = [judge(run(rng, 1e-3, 3e-4, passes), run(rng, 1e-3, 3e-4, passes), 0.0, 0.99).verdict
                for _ in range(1000)]
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
    # True change +20 % with a 5 % tolerance, pass noise 60 %: undecided with 8 passes each.
    def measured(value, passes):
        return Measurement(value, 0.6 / math.sqrt(passes) * t_factor(passes), 0.0, passes, passes * 100_000,
                           float(passes))

    old, new = measured(1.0, 8), measured(1.2, 8)
    v = judge(old, new, 0.05, 0.99)
    assert v.verdict == UNDECIDED and v.more_photons > 0 and v.more_time_s > 0
    a_old, a_new = v.more_passes
    assert v.more_photons == 100_000 * (a_old + a_new) and v.more_time_s == pytest.approx(a_old + a_new)
    # Give the runs the passes it asks for (errors fall as 1/sqrt(passes), same pass spread) and it
    # decides; and no split of 10 % fewer passes does (every split tried, by brute force).
    assert judge(measured(1.0, 8 + a_old), measured(1.2, 8 + a_new), 0.05, 0.99).verdict == REGRESSION
    total = int(0.9 * (a_old + a_new))
    assert all(judge(measured(1.0, 8 + k), measured(1.2, 8 + total - k), 0.05, 0.99).verdict == UNDECIDED
               for k in range(total + 1))


def test_the_cheaper_run_takes_the_passes():
    # Same spread per pass, but the new run's passes cost 10x: the old run takes most of them.
    old = Measurement(1.0, 0.1 * t_factor(8), 0.0, 8, 800_000, 8.0)
    new = Measurement(1.2, 0.1 * t_factor(8), 0.0, 8, 800_000, 80.0)
    a_old, a_new = judge(old, new, 0.05, 0.99).more_passes
    assert a_old > 2 * a_new


def test_bias_bounds_widen_the_interval_and_can_make_photons_useless():
    old = Measurement(1.0, 0.001, 0.1, 32)
    new = Measurement(1.1, 0.001, 0.1, 32)
    v = judge(old, new, 0.05, 0.99)
    assert v.verdict == UNDECIDED and v.more_photons is None and "bias" in v.note
    assert v.high - v.low > 0.4  # the two bounds, on both sides


def test_one_pass_has_no_error_bar():
    v = judge(Measurement(1.0, None, 0.0, 1), Measurement(2.0, 0.1, 0.0, 8))
    assert v.verdict == UNDECIDED and math.isinf(v.low)


def test_no_signal_in_either_run_is_judged_through_the_bounds():
    # Both read exactly zero: the change lies within [-U_old, U_new], undecided unless the bounds
    # clear the tolerance (0 here: old is 0), so never a regression.
    v = judge(Measurement(0.0, 0.0, 0.0, 8, no_signal_bound=1e-8), Measurement(0.0, 0.0, 0.0, 8, no_signal_bound=1e-8))
    assert v.verdict == UNDECIDED and v.low < 0 < v.high and v.change == 0 and "no signal" in v.note


def test_an_all_zero_run_enters_through_its_upper_bound():
    """An all-zero run is not an exact zero: old 1.42e-8 against it must not read "improvement", nor the
    reverse "regression" (exit 1). The zero run's bound U (95 %: 3 photons' worth)
    is the most it could be; at 99 % it is U · ln(1/0.0025) / 3."""
    rng = np.random.default_rng(11)
    old = of_passes(rng.normal(1.42e-8, 0.3e-8, 4))
    zero = Measurement(0.0, 0.0, 0.0, 4, 40_000, 4.0, no_signal_bound=2e-8)  # the bound is above old's value
    for a, b in ((old, zero), (zero, old)):
        v = judge(a, b, 0.05, 0.99)
        assert v.verdict == UNDECIDED and not v.regression, v
        assert v.low < 0 < v.high
    # The bound decides only when it lies clear of the other run: a tiny bound under a clear signal.
    small = Measurement(0.0, 0.0, 0.0, 64, 640_000, 64.0, no_signal_bound=1e-10)
    assert judge(small, old, 0.05, 0.99).verdict == REGRESSION
    assert judge(old, small, 0.05, 0.99).verdict == IMPROVEMENT
    # The regression's low end is old's lower end minus the zero run's bound at its share of the tail.
    v = judge(small, old, 0.05, 0.99)
    assert v.low == pytest.approx(interval(small, old, 0.99)[0])
    assert v.low < old.value - 1e-10 * math.log(1 / 0.0025) / 3


def test_an_all_zero_run_is_never_a_regression_unless_its_bound_decides_it():
    # Over many noisy pairs of a signal near the zero run's bound, "regression" needs the new run's
    # lower end above the bound, and that happens only where the bound (not 0 ± 0) is exceeded.
    rng = np.random.default_rng(12)
    for _ in range(300):
        zero = Measurement(0.0, 0.0, 0.0, 4, 40_000, 4.0, no_signal_bound=float(rng.uniform(0.5, 2.0)))
        new = of_passes(rng.gamma(2.0, 0.5, int(rng.integers(3, 9))))
        v = judge(zero, new, 0.05, 0.99)
        assert v.regression == (v.low > 0)
        lower_end = interval(zero, Measurement(new.value, new.std_error, 0.0, new.passes, no_signal_bound=None), 0.99)[0]
        assert v.low == pytest.approx(lower_end)
        if v.regression:
            assert new.value > zero.bound(0.0025)


def test_zero_without_a_bound_decides_nothing():
    v = judge(Measurement(1.0, 0.01, 0.0, 8), Measurement(0.0, 0.0, 0.0, 8))
    assert v.verdict == UNDECIDED and "no bound" in v.note


@pytest.mark.parametrize("text,value", [("5%", 0.05), ("0.05", 0.05), ("99 %", 0.99), (" 1e-2 ", 0.01)])
def test_fractions(text, value):
    assert parse_fraction(text, "--tolerance") == pytest.approx(value)


def test_bad_fraction_names_the_field():
    with pytest.raises(ValueError, match="--confidence"):
        parse_fraction("lots", "--confidence")


def _until_decided(rng, change, confidence, tolerance=0.1, start=4, max_passes=2000, spend=True):
    """compare --until-decided on synthetic runs (pass spread 30 %): look j at look_confidence(c, j)
    (or at c every time when spend is False), then the passes `to_decide` asks for at the next look's."""
    from lensmount.analysis.compare import look_confidence, to_decide

    old, new = list(rng.normal(1.0, 0.3, start)), list(rng.normal(1.0 + change, 0.3, start))
    for look in range(1, 13):
        c = look_confidence(confidence, look) if spend else confidence
        v = judge(of_passes(old), of_passes(new), tolerance, c)
        if v.verdict != UNDECIDED:
            return v.verdict, len(old) + len(new)
        more = to_decide(of_passes(old), of_passes(new), v.threshold,
                         look_confidence(confidence, look + 1) if spend else confidence)
        if more is None or len(old) + len(new) + sum(more) > max_passes:
            return UNDECIDED, len(old) + len(new)
        old += list(rng.normal(1.0, 0.3, more[0]))
        new += list(rng.normal(1.0 + change, 0.3, more[1]))
    return UNDECIDED, len(old) + len(new)


def test_looking_again_until_decided_keeps_the_error_rate():
    """Resuming undecided runs and judging again spends the error once per look. With the
    looks' shares α · 6/(π² j²) the wrong verdicts stay within 1 − c over whole sequences: at c = 0.9
    same-design pairs (true change 0, tolerance 10 %) read "regression" at most (1 − c)/2 = 5 % of the
    time; at c at every look the same sequences do so more often."""
    from lensmount.analysis.compare import look_confidence

    assert sum(1 - look_confidence(0.9, j) for j in range(1, 100_000)) == pytest.approx(0.1, rel=1e-4)
    rng = np.random.default_rng(21)
    spent = [_until_decided(rng, 0.0, 0.9) for _ in range(200)]
    rng = np.random.default_rng(21)
    naive = [_until_decided(rng, 0.0, 0.9, spend=False) for _ in range(200)]
    rate = sum(v == REGRESSION for v, _ in spent) / 200
    assert rate <= 0.05, rate
    assert sum(v == REGRESSION for v, _ in naive) / 200 > rate
    # Most sequences end at "no regression" well within the budget.
    assert sum(v in (NO_REGRESSION, IMPROVEMENT) for v, _ in spent) / 200 > 0.7


def test_until_decided_reaches_a_real_regression():
    rng = np.random.default_rng(22)
    verdicts = [_until_decided(rng, 0.25, 0.99, tolerance=0.05)[0] for _ in range(50)]
    assert verdicts.count(REGRESSION) >= 48


REAL_PASSES = Path(__file__).parent / "data" / "case2-small-forward-passes.txt"


@pytest.mark.parametrize("name,draw,passes", [
    ("normal", lambda rng, n: rng.normal(1.0, 0.3, n), (4, 4)),
    # the real forward passes' spread (53 %) and skew: few photons reach the detector per pass
    ("gamma 3.4", lambda rng, n: rng.gamma(3.4, 0.3, n), (4, 8)),
    ("real case-2 passes", None, (4, 4)),
])
def test_the_interval_covers_a_zero_change_at_its_confidence_not_more(name, draw, passes):
    """The summaries' errors are t-widened; compare takes that back and widens once (widened twice, a
    nominal 99 % interval covered 99.95 %). Over 1000 same-design pairs it must cover between 98.5 % and
    99.5 %. The real case is 1000 pairs of 4-pass runs drawn from 2000 real passes of 250 seeds
    (every pair's 8 passes distinct)."""
    rng = np.random.default_rng(31)
    pool = np.loadtxt(REAL_PASSES).ravel() if draw is None else None
    covered = 0
    for _ in range(1000):
        if pool is not None:
            x = rng.choice(pool, sum(passes), replace=False)
            a, b = x[:passes[0]], x[passes[0]:]
        else:
            a, b = draw(rng, passes[0]), draw(rng, passes[1])
        low, high = interval(of_passes(a), of_passes(b), 0.99)
        covered += low <= 0 <= high
    assert 985 <= covered <= 995, covered


def test_a_run_whose_terms_give_no_error_bar_decides_nothing():
    """A run whose passes' terms are too heavy-tailed for an error bar has an infinite standard error
    (`Accumulator.flux_std_error`): the verdict is undecided and says why, and no number of passes is promised
    (it raised ValueError on the NaN share of the passes to add)."""
    heavy, plain = Measurement(1.0, math.inf, 0.0, 4, 8000, 4.0), Measurement(1.5, 0.01, 0.0, 4, 8000, 4.0)
    for old, new in ((heavy, plain), (plain, heavy)):
        v = judge(old, new, 0.0, 0.99)
        assert v.verdict == UNDECIDED and "heavy-tailed" in v.note, v
        assert to_decide(old, new, 0.0, 0.99) is None
