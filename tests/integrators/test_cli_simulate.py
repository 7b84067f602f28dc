"""`lensmount simulate`: bad input is one paragraph and exit code 2; same seed, same summary (slow)."""

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lensmount.cli import app

DESIGN = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"
SCENE = DESIGN / "scenes" / "case1-diaphragm-edge.toml"


@pytest.mark.parametrize("args,needle", [
    (["--method", "sideways"], "--method"),
    (["--alpha", "1.5"], "--alpha"),
    (["--target-rel-error", "0"], "--target-rel-error"),
    (["--photons", "0"], "--photons"),
])
def test_bad_options_are_input_errors(tmp_path, args, needle):
    result = CliRunner().invoke(app, ["simulate", str(DESIGN), "--scene", str(SCENE), "--out", str(tmp_path)] + args)
    assert result.exit_code == 2, result.output
    assert needle in result.output and "Traceback" not in result.output


def test_resume_without_checkpoint_is_an_input_error(tmp_path):
    result = CliRunner().invoke(app, ["simulate", str(DESIGN), "--scene", str(SCENE), "--out", str(tmp_path),
                                      "--resume"])
    assert result.exit_code == 2 and "checkpoint" in result.output


@pytest.mark.slow
def test_same_seed_same_summary_any_workers(tmp_path):
    def run(out, workers):
        result = CliRunner().invoke(app, ["simulate", str(DESIGN), "--scene", str(SCENE), "--out", str(out),
                                          "--passes", "3", "--photons-per-pass", "20000", "--seed", "4",
                                          "--workers", str(workers)])
        assert result.exit_code == 0, result.output
        s = json.loads((out / "summary.json").read_text())
        for volatile in ("time_s", "workers", "design", "scene"):
            s.pop(volatile)
        return s

    a = run(tmp_path / "a", 1)
    b = run(tmp_path / "b", 1)
    c = run(tmp_path / "c", 2)
    assert a == b == c
    assert a["passes"] == 3 and a["seed"] == 4 and a["method"] == "bidirectional"
    for key in ("stray_fraction", "stray_fraction_std_error", "photons", "effects", "per_part", "input_hash",
                "mean_irradiance", "peak_irradiance", "stray_fraction_drift", "lost_flux"):
        assert key in a
