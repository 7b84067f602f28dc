"""The analysis commands from the command line: ghosts, fit-abg, sweep's input errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lensmount.cli import app

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "lensmount" / "examples"


@pytest.mark.slow  # a cold regenerate of the triplet and its tracer
def test_ghosts_of_the_uncoated_cooke_triplet(tmp_path):
    design = tmp_path / "cooke"
    shutil.copytree(EXAMPLES / "cooke-triplet-uncoated", design)
    out = tmp_path / "ghosts"
    result = CliRunner().invoke(app, ["ghosts", str(design), "--scene", str(design / "scenes" / "ghosts-uncoated.toml"),
                                      "--out", str(out), "--rays-across", "41", "--top", "3"])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "ghosts.json").read_text())
    pairs = report["pairs"]
    assert len(pairs) >= 10  # six glass surfaces: up to 15 pairs, the mount vignettes some
    peaks = [p["peak_irradiance"] for p in pairs]
    assert peaks == sorted(peaks, reverse=True) and peaks[0] > 0
    assert abs(sum(p["share"] for p in pairs) - 1.0) < 1e-9
    assert (out / "ghosts.exr").exists() and len(list(out.glob("ghost-*.png"))) == 3
    # Order 3: the four-reflection routes join (named in the order the light meets them), ~1.7 % more light.
    # On the same lattice (41 across): the lattice's own error is larger than that (the two-reflection total
    # at 21 across is 2.2 % below its value at 41, 3.8 % below 101), so totals of two lattices cannot show it.
    result = CliRunner().invoke(app, ["ghosts", str(design), "--scene", str(design / "scenes" / "ghosts-uncoated.toml"),
                                      "--out", str(tmp_path / "order3"), "--rays-across", "41", "--order", "3",
                                      "--top", "1"])
    assert result.exit_code == 0, result.output
    deeper = json.loads((tmp_path / "order3" / "ghosts.json").read_text())
    fours = [p for p in deeper["pairs"] if p["reflections"] == 4]
    assert deeper["order"] == 3 and len(fours) > 100 and all(len(p["surfaces"]) == 4 for p in fours)
    twos = sum(p["fraction"] for p in deeper["pairs"] if p["reflections"] == 2)
    assert twos == pytest.approx(report["total_fraction"], rel=1e-9)  # the same routes, the same rays
    assert 1.005 < deeper["total_fraction"] / report["total_fraction"] < 1.05


def test_fit_abg_prints_the_finish_lines(tmp_path):
    rows = ["incidence_deg,scatter_deg,brdf"]
    import math

    for inc in (0.0, 30.0, 60.0):
        for sc in range(-85, 90, 5):
            rho = abs(math.sin(math.radians(sc)) - math.sin(math.radians(inc)))
            rows.append(f"{inc},{sc},{2e-3 / (1e-3 + rho ** 2):.8e}")
    (tmp_path / "paint.csv").write_text("\n".join(rows) + "\n")
    result = CliRunner().invoke(app, ["fit-abg", str(tmp_path / "paint.csv"), "--plot", str(tmp_path / "fit.png")])
    assert result.exit_code == 0, result.output
    assert 'model = "abg", A = 0.002, B = 0.001, g = 2 }' in result.output
    assert (tmp_path / "fit.png").stat().st_size > 0
    assert "rms error 0.000 decades" in result.output and "poor fit" not in result.output


def test_fit_abg_warns_on_a_poor_fit_and_its_help_keeps_the_brackets(tmp_path):
    """A fit that misses by decades (0.59-decade rms) is not accepted without a word, and --help keeps
    "[finishes]" (not eaten as rich markup). A BRDF with a second, wide lobe 1000x below the specular peak
    is no ABg curve: the fit misses it by decades."""
    import math

    rows = ["incidence_deg,scatter_deg,brdf"]
    for inc in (0.0, 30.0):
        for sc in range(-85, 90, 5):
            rho = abs(math.sin(math.radians(sc)) - math.sin(math.radians(inc)))
            brdf = 2e-3 / (1e-4 + rho ** 3) + (1.0 if 0.3 < rho < 0.6 else 0.0)
            rows.append(f"{inc},{sc},{brdf:.8e}")
    (tmp_path / "bumpy.csv").write_text("\n".join(rows) + "\n")
    result = CliRunner().invoke(app, ["fit-abg", str(tmp_path / "bumpy.csv")])
    assert result.exit_code == 0, result.output
    rms = float(result.output.split("rms error ")[1].split()[0])
    assert rms > 0.2 and "warning: a poor fit" in result.output and "measured table" in result.output
    help_text = CliRunner().invoke(app, ["fit-abg", "--help"], env={"COLUMNS": "200"}).output
    assert "[finishes]" in help_text


def test_fit_abg_bad_file_is_exit_2(tmp_path):
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    result = CliRunner().invoke(app, ["fit-abg", str(tmp_path / "x.csv")])
    assert result.exit_code == 2 and "x.csv" in result.output and "Traceback" not in result.output


def test_sweep_bad_param_is_exit_2_before_anything_is_built(tmp_path):
    design = EXAMPLES / "double-gauss-360"
    result = CliRunner().invoke(app, ["sweep", str(design), "--scene", str(design / "scenes" / "case2-lambertian.toml"),
                                      "--param", "vanes.count=3,5", "--out", str(tmp_path / "s")])
    assert result.exit_code == 2 and "--param" in result.output
    assert not (tmp_path / "s").exists()
