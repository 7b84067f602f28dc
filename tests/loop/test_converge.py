"""converge: doubling levels, the fitted slope and the halving time, its CSV and plot, bad input."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.loop.converge import (
    Level, MethodCurve, _curve, fit_slope, halving_time, level_times, read_reference, write_converge)
from lensmount.cli import app
from lensmount.errors import InputError
from lensmount.loop.progress import PassStatus

DESIGN = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


def test_levels_double_up_to_the_budget():
    assert level_times(160, 5) == [10, 20, 40, 80, 160]


def test_slope_and_halving_time_of_an_ideal_monte_carlo_error():
    t = [10, 20, 40, 80]
    assert fit_slope(t, [0.1 / math.sqrt(x / 10) for x in t]) == pytest.approx(-0.5)
    assert halving_time(80, -0.5) == pytest.approx(240)  # 4× the time in all
    assert halving_time(80, -1.0) == pytest.approx(80)
    assert halving_time(80, 0.1) is None and fit_slope([10], [0.1]) is None


def test_levels_are_read_from_the_passes_of_one_run():
    """Passes of a Gaussian estimator with known σ: each level's error is the batch-means error then."""
    rng = np.random.default_rng(4)
    values = 1.0 + 0.2 * rng.standard_normal(64)
    statuses = []
    for n in range(1, 65):
        v = values[:n]
        se = float(np.std(v, ddof=1) / math.sqrt(n)) if n > 1 else None
        statuses.append(PassStatus(n, 1000 * n, 0.5 * n, float(v.mean()), se,
                                   se / float(v.mean()) if se else math.inf, None, None, None, None))
    curve = _curve("forward", statuses, level_times(32, 5), {"stray_fraction_bias_bound": 0.01}, reference=1.0)
    assert [lv.passes for lv in curve.levels] == [4, 8, 16, 32, 64]
    assert curve.levels[-1].bias_bound == 0.01 and curve.levels[0].bias_bound is None
    assert curve.slope == pytest.approx(-0.5, abs=0.2)  # σ/√n with noisy batch-means estimates
    assert curve.levels[-1].rel_error_vs_reference == pytest.approx(abs(values.mean() - 1.0))
    assert curve.halving_rate == "fitted" and curve.next_halving_s > 0


def test_an_implausible_slope_falls_back_to_the_monte_carlo_rate():
    """A flat error over 2–5 passes is noise in the error bars: the halving time is 3·t, not hours."""
    statuses = [PassStatus(n, 1000 * n, 10.0 * n, 1.0, 0.01, 0.01, None, None, None, None) for n in range(1, 17)]
    curve = _curve("forward", statuses, level_times(160, 5), {}, reference=None)
    assert curve.slope == pytest.approx(0.0, abs=1e-9)
    assert curve.halving_rate == "1/√t" and curve.next_halving_s == pytest.approx(3 * 160)


def test_reference_from_a_number_or_a_summary(tmp_path):
    assert read_reference("1.5e-6") == 1.5e-6 and read_reference(None) is None
    (tmp_path / "summary.json").write_text(json.dumps({"stray_fraction": 2e-6}))
    assert read_reference(str(tmp_path / "summary.json")) == 2e-6
    for bad in ("-1", str(tmp_path / "missing.json"), "nan"):
        with pytest.raises(InputError):
            read_reference(bad)


def test_csv_and_plot(tmp_path):
    levels = [Level("forward", k, 10 * 2**k, 4 * 2**k, 4000 * 2**k, 1e-5, 1e-6 / 2 ** (k / 2), 0.1 / 2 ** (k / 2),
                    None, 0.05 / 2 ** (k / 2)) for k in range(3)]
    paths = write_converge(tmp_path, [MethodCurve("forward", levels, -0.5, 120.0)], reference=1e-5)
    rows = paths["csv"].read_text().splitlines()
    assert rows[0].split(",")[:3] == ["method", "level", "time_s"] and len(rows) == 4
    assert "nan" not in paths["csv"].read_text().lower()
    assert paths["png"].read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args,needle", [(["--methods", "sideways"], "--methods"), (["--budget", "0"], "--budget"),
                                         (["--levels", "1"], "--levels"), (["--reference", "-2"], "--reference")])
def test_bad_input_is_one_paragraph_and_exit_2(tmp_path, args, needle):
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["converge", str(DESIGN), "--scene", str(DESIGN / "scenes" / "case2-lambertian.toml"),
                                      "--out", str(out)] + args)
    assert result.exit_code == 2, result.output
    assert needle in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_a_run_where_nothing_reached_the_detector_has_no_error_bar():
    """Forward photons may all miss a 50 µm edge: a zero with zero spread is not a 0 % error."""
    statuses = [PassStatus(n, 1000 * n, float(n), 0.0, 0.0, 0.0, None, None, None, None) for n in range(1, 9)]
    curve = _curve("forward", statuses, level_times(8, 3), {}, reference=1e-8)
    assert all(lv.rel_std_error is None for lv in curve.levels)
    assert curve.slope is None and curve.next_halving_s is None


def test_the_relative_standard_error_column_is_the_standard_error_alone():
    """`rel_std_error` is se/value (the 1/√t curve), not (se + bias)/value, which sits beside it as
    `rel_error` (what --target-rel-error stops on)."""
    statuses = [PassStatus(n, 1000 * n, 10.0 * n, 2.0, 0.1, 0.15, None, None, None, None) for n in range(1, 9)]
    curve = _curve("bidirectional", statuses, level_times(80, 3), {"stray_fraction_bias_bound": 0.1}, reference=None)
    assert all(lv.rel_std_error == pytest.approx(0.05) and lv.rel_error == pytest.approx(0.15) for lv in curve.levels)
