"""simulate's progress arithmetic: error ∝ 1/√t gives the ETA, the trend and the cost of a halving."""

import math

import pytest

from lensmount.cli.simulate import describe
from lensmount.loop.progress import PassStatus
from lensmount.loop.progress import error_slope, next_halving_s, status_of, time_to_error


def test_eta_follows_inverse_square_of_the_error():
    # 10 % after 60 s: 5 % needs 4x the time in all, so 180 s more; 2.5 % needs 16x, 900 s more.
    assert time_to_error(60.0, 0.10, 0.05) == pytest.approx(180.0)
    assert time_to_error(60.0, 0.10, 0.025) == pytest.approx(900.0)
    assert time_to_error(60.0, 0.04, 0.05) == 0.0
    assert time_to_error(60.0, math.inf, 0.05) is None
    assert next_halving_s(60.0) == pytest.approx(180.0)


def test_trend_of_a_healthy_run_is_minus_one_half():
    history = [(t, 0.3 / math.sqrt(t)) for t in range(1, 40)]
    assert error_slope(history) == pytest.approx(-0.5, abs=1e-9)
    stuck = [(t, 0.1) for t in range(1, 40)]  # an error that does not fall (bias, or a broken estimator)
    assert error_slope(stuck) == pytest.approx(0.0, abs=1e-9)
    assert error_slope(history[:3]) is None  # too few points to say


def test_one_plain_line_per_pass_says_value_error_trend_and_eta():
    s = PassStatus(passes=12, photons=1_200_000, elapsed_s=60.0, value=1.234e-3, std_error=1.2e-4, rel_error=0.0972,
                   error_slope=-0.49, target_rel_error=0.05, eta_s=time_to_error(60.0, 0.0972, 0.05), max_passes=None)
    line = describe(s)
    assert "\n" not in line
    for needle in ("pass 12", "1,200,000 photons", "0.001234 ± 0.00012", "9.72 %", "t^-0.49", "target 5 %",
                   "in ~3 min"):
        assert needle in line, (needle, line)


def test_a_run_whose_relative_error_is_unknown_says_why_and_promises_no_time():
    """A zero-signal run (a ± of 0, no relative error) must not read "target 10 % in ~0 s"."""
    from lensmount.analysis.passes import Accumulator

    import numpy as np

    from lensmount.integrators.estimate import PassEstimate

    acc = Accumulator.empty((2, 2), ["barrel"], 1.0)
    for _ in range(4):
        acc.add(PassEstimate(np.zeros((2, 2)), np.zeros((1, 2, 2)), ["barrel"], 1.0, 1000))
    s = status_of(acc, 40.0, 10.0, 0.1, None, [])
    line = describe(s)
    assert s.eta_s is None and "in ~0 s" not in line and "rel. error unknown (no signal yet)" in line, line
    assert "target 10 % in a time not known yet" in line


def test_the_summary_points_to_a_tail_warning_only_when_one_is_printed(capsys, monkeypatch):
    from lensmount.cli.simulate import print_summary

    monkeypatch.setenv("COLUMNS", "200")  # one table row a line

    summary = {"method": "bidirectional", "passes": 24, "photons": 480_000, "time_s": 41.0, "stray_fraction": 5.4e-4,
               "stray_fraction_std_error": 3e-6, "stray_fraction_rel_error": 0.006, "stray_fraction_tail_allowance": 1e-7,
               "tail": {"heavy": False, "terms_tail_index": 2.6, "largest_over_median": 1.03}, "warnings": [],
               "units": {"irradiance": "E/E_sun"}, "peak_irradiance": 1e-3, "effects": ["scatter"],
               "effects_skipped": [], "per_part": {}}
    print_summary(summary, {})
    quiet = capsys.readouterr().out
    assert "warning" not in quiet and "tail allowance" in quiet and "x^-2.60" in quiet, quiet
    summary["tail"]["note"] = "the largest terms the passes sum fall off as x^-2.60 (below 3): a heavy tail"
    print_summary(summary, {})
    said = capsys.readouterr().out
    assert "warning: the largest terms" in said and "see the warning" in said, said
