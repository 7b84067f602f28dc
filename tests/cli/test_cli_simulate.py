"""`lensmount simulate`: bad input is one paragraph and exit code 2 with nothing written; same seed, same summary (slow)."""

import json
import os
import shutil
from pathlib import Path

import numpy as np

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
    (["--time", "-1"], "--time"),
    (["--time", "0"], "--time"),
    (["--workers", "-1"], "--workers"),
    (["--seed", "-3"], "--seed"),
])
def test_bad_options_are_input_errors(tmp_path, args, needle):
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["simulate", str(DESIGN), "--scene", str(SCENE), "--out", str(out)] + args)
    assert result.exit_code == 2, result.output
    assert needle in result.output and "Traceback" not in result.output
    assert not out.exists()


def _design_copy(tmp_path) -> Path:
    design = tmp_path / "design"
    shutil.copytree(DESIGN, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    return design


def _read_only_folder(tmp_path) -> Path:
    """A folder this process cannot write: mode 0555, or /sys for root (permissions do not bind root)."""
    if os.geteuid() == 0:
        return Path("/sys")
    ro = tmp_path / "read-only"
    ro.mkdir()
    ro.chmod(0o555)
    return ro


def test_read_only_output_is_refused_before_the_build(tmp_path):
    design = _design_copy(tmp_path)
    out = _read_only_folder(tmp_path)
    result = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / SCENE.name),
                                      "--out", str(out), "--passes", "1"])
    assert result.exit_code == 2, result.output
    assert "--out" in result.output and str(out) in result.output and "Traceback" not in result.output
    assert not (design / "build").exists()  # refused before the mount was built
    assert not (design / ".lensmount").exists()


def test_resume_mismatch_names_what_the_checkpoint_holds(tmp_path):
    from lensmount.analysis.passes import Accumulator

    design = _design_copy(tmp_path)
    out = tmp_path / "out"
    acc = Accumulator.empty((2, 2), ["barrel"], 1.0)
    acc.save(out / "checkpoint.npz", seed=3, method="forward", input_hash="0123abcd")
    before = (out / "checkpoint.npz").read_bytes()
    result = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / SCENE.name),
                                      "--out", str(out), "--resume", "--seed", "5"])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    # what it holds -> what was asked, and the input hash when no summary.json beside it says more
    assert "seed 3 -> 5" in text and "method forward -> bidirectional" in text and "input hash 0123abcd" in text
    assert "field 'seed'" in text
    assert sorted(p.name for p in out.iterdir()) == ["checkpoint.npz"]
    assert (out / "checkpoint.npz").read_bytes() == before
    assert not (design / "build").exists()


def test_resume_of_a_checkpoint_of_an_older_layout_is_one_paragraph(tmp_path):
    from lensmount.analysis.passes import Accumulator

    out = tmp_path / "out"
    Accumulator.empty((2, 2), ["barrel"], 1.0).save(out / "checkpoint.npz", seed=1)
    with np.load(out / "checkpoint.npz") as z:
        arrays = {k: z[k] for k in z.files if not k.startswith(("paths_", "faces_"))}
    arrays["version"] = np.int64(5)  # before path signatures
    np.savez(out / "checkpoint.npz", **arrays)
    result = CliRunner().invoke(app, ["simulate", str(DESIGN), "--scene", str(SCENE), "--out", str(out), "--resume"])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert "version 5" in text and "checkpoint.npz" in text and "without --resume" in text
    assert "Traceback" not in text


def test_paths_of_a_folder_without_path_data_is_one_paragraph(tmp_path):
    result = CliRunner().invoke(app, ["paths", str(tmp_path)])
    assert result.exit_code == 2, result.output
    assert "paths.npz" in " ".join(result.output.split()) and "Traceback" not in result.output


def test_resume_without_checkpoint_starts_the_run_and_says_so(tmp_path):
    """A run stopped before its first pass keeps nothing; a batch script's retry with --resume then
    starts it (docs/scale.md) and says there was nothing to resume."""
    result = CliRunner().invoke(app, ["simulate", str(DESIGN), "--scene", str(SCENE), "--out", str(tmp_path),
                                      "--resume", "--passes", "1", "--photons-per-pass", "500", "--workers", "1",
                                      "--no-record"])
    assert result.exit_code == 0, result.output
    assert "nothing to resume" in result.output and (tmp_path / "summary.json").is_file()


@pytest.mark.slow
def test_same_seed_same_summary_any_workers(tmp_path):
    design = _design_copy(tmp_path)
    scene = design / "scenes" / "small.toml"  # determinism does not need the 600² view map
    scene.write_text((design / "scenes" / SCENE.name).read_text().replace("[600, 600]", "[120, 120]"))

    def run(out, workers):
        result = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(scene),
                                          "--out", str(out),
                                          "--passes", "3", "--photons-per-pass", "5000", "--seed", "4",
                                          "--workers", str(workers)])
        assert result.exit_code == 0, result.output
        s = json.loads((out / "summary.json").read_text())
        for volatile in ("time_s", "workers", "provenance", "sha256"):  # sha256: of the summary, times too
            s.pop(volatile)
        s["plan"].pop("time_s")  # seconds per phase
        s["plan"].pop("wall_time_s")
        return s

    a = run(tmp_path / "a", 1)
    b = run(tmp_path / "b", 1)
    c = run(tmp_path / "c", 2)
    assert a == b == c
    assert a["passes"] == 3 and a["seed"] == 4 and a["method"] == "bidirectional"
    for key in ("stray_fraction", "stray_fraction_std_error", "photons", "effects", "per_part", "input_hash",
                "mean_irradiance", "peak_irradiance", "stray_fraction_drift", "lost_flux"):
        assert key in a


@pytest.mark.slow
def test_sun_behind_the_entrance_plane_reads_zero_and_says_why(tmp_path):
    design = _design_copy(tmp_path)
    scene = design / "scenes" / "behind.toml"
    text = (design / "scenes" / "case2-lambertian.toml").read_text()
    scene.write_text(text.replace("off_axis_deg = 7.0", "off_axis_deg = 120.0").replace("[600, 600]", "[20, 20]"))
    result = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(scene), "--out", str(tmp_path / "o"),
                                      "--method", "forward", "--passes", "2", "--photons-per-pass", "2000",
                                      "--workers", "1"])
    assert result.exit_code == 0, result.output
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["stray_fraction"] == 0 and s["aperture_flux_mm2"] == 0
    assert "behind the entrance plane" in s["no_light_enters"]
    assert "no light enters" in " ".join(result.output.split())
