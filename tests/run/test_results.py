"""Result files: EXR channels round trip, PNG written, JSON refuses NaN, nothing half-written."""

import json

import numpy as np
import pytest

from lensmount.analysis.passes import Accumulator
from lensmount.integrators.estimate import PassEstimate
from lensmount.run.results import read_exr, read_summary, write_run, write_summary


def _acc():
    acc = Accumulator.empty((6, 8), ["diaphragm", "barrel", "hood"], 0.01)
    rng = np.random.default_rng(0)
    for _ in range(3):
        img = rng.random((6, 8))
        parts = np.stack([img * 0.4, img * 0.6, np.zeros_like(img)])
        acc.add(PassEstimate(img, parts, acc.part_names, 0.01, 10))
    return acc


def test_write_run_files(tmp_path):
    acc = _acc()
    summary = {"method": "bidirectional", "passes": acc.n, "stray_fraction": 1e-4, "unknown": None}
    paths = write_run(tmp_path / "out", acc, summary, extent_mm=(-4, 4, -3, 3), field_radius_mm=3.0)
    ch = read_exr(paths["exr"])
    assert set(ch) == {"Y", "diaphragm", "barrel"}  # hood contributes nothing
    assert ch["Y"].dtype == np.float32 and ch["Y"].shape == (6, 8)
    np.testing.assert_allclose(ch["Y"], acc.mean_image, rtol=1e-6)
    np.testing.assert_allclose(ch["diaphragm"] + ch["barrel"], ch["Y"], rtol=1e-5)
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads(paths["json"].read_text())["passes"] == 3
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.endswith(".tmp")]


def test_summary_refuses_nan_and_keeps_old_file(tmp_path):
    path = tmp_path / "summary.json"
    write_summary(path, {"a": 1})
    with pytest.raises(ValueError):
        write_summary(path, {"a": float("nan")})
    assert read_summary(path) == {"a": 1}  # the old file, whole (its checksum holds)
    assert len(list(tmp_path.iterdir())) == 1


def test_preview_of_an_all_zero_image(tmp_path):
    acc = Accumulator.empty((4, 4), ["p"], 1.0)
    z = np.zeros((4, 4))
    acc.add(PassEstimate(z, z[None], ["p"], 1.0, 1))
    paths = write_run(tmp_path, acc, {"method": "forward"})
    assert paths["png"].stat().st_size > 0
    assert set(read_exr(paths["exr"])) == {"Y"}


def test_display_binning_keeps_a_converged_image_and_coarsens_a_speckled_one():
    from lensmount.run.results import display_binning

    rng = np.random.default_rng(3)
    smooth = np.full((60, 60), 2.0)
    b, shown = display_binning(smooth, 0.01 * smooth)
    assert b == 1 and np.array_equal(shown, smooth)
    # 5 % of pixels lit, each with 100 % error: bins must hold ~16+ lit pixels for 25 %.
    speckle = np.where(rng.random((60, 60)) < 0.05, 1.0, 0.0)
    b, shown = display_binning(speckle, speckle.copy())
    assert b >= 10 and 60 % b == 0
    assert shown.shape == (60 // b, 60 // b)
    assert np.isclose(shown.mean(), speckle.mean())  # binning preserves the mean irradiance


def test_display_binning_of_a_dark_image_is_the_image():
    from lensmount.run.results import display_binning

    dark = np.zeros((6, 4))
    assert display_binning(dark, dark)[0] == 1
