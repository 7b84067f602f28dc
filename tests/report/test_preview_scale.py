"""Previews meant to be compared share one colour scale and one pixel binning."""

import re

import numpy as np
import pytest

from lensmount.run.report import run_report
from lensmount.run.results import block_mean, display_binning, preview_scale, shared_scale, write_difference


def test_block_mean_conserves_the_mean_and_refuses_uneven_blocks():
    img = np.arange(24.0).reshape(4, 6)
    assert block_mean(img, 2).mean() == pytest.approx(img.mean())
    assert block_mean(img, 2)[0, 0] == pytest.approx((0 + 1 + 6 + 7) / 4)
    with pytest.raises(ValueError):
        block_mean(img, 4)


def test_shared_scale_takes_the_coarsest_binning_and_covers_both_ranges():
    rng = np.random.default_rng(5)
    smooth = np.full((60, 60), 2.0)
    speckle = np.where(rng.random((60, 60)) < 0.05, 40.0, 0.0)
    s = shared_scale([(smooth, 0.01 * smooth), (speckle, speckle.copy())])
    assert s.block == max(display_binning(smooth, 0.01 * smooth)[0], display_binning(speckle, speckle)[0]) > 1
    shown = [block_mean(smooth, s.block), block_mean(speckle, s.block)]
    assert s.vmax == pytest.approx(max(float(v.max()) for v in shown))
    assert 0 < s.vmin <= min(float(v[v > 0].min()) for v in shown) * 1.0001 or s.vmin >= s.vmax * 1e-6
    with pytest.raises(ValueError):
        shared_scale([(smooth, smooth), (smooth[:30], smooth[:30])])


def test_preview_scale_of_dark_images_is_valid():
    s = preview_scale([np.zeros((4, 4))])
    assert 0 < s.vmin < s.vmax


def test_difference_is_signed_new_minus_old(tmp_path):
    old = np.ones((8, 8))
    new = old.copy()
    new[:4] *= 3.0  # brighter in the lower half of the new run
    new[4:] *= 0.5
    s = preview_scale([old, new], block=2)
    diff = write_difference(tmp_path / "d.png", new, old, (-4, 4, -4, 4), s)
    assert diff.shape == (4, 4)
    np.testing.assert_allclose(diff[:2], 2.0)
    np.testing.assert_allclose(diff[2:], -0.5)
    assert (tmp_path / "d.png").read_bytes()[:4] == b"\x89PNG"


def test_run_report_has_no_external_reference_and_no_nan(tmp_path):
    png = tmp_path / "p.png"
    write_difference(png, np.ones((2, 2)), np.zeros((2, 2)), (0, 1, 0, 1), preview_scale([np.ones((2, 2))]))
    doc = run_report({"stray_fraction": 1e-5, "stray_fraction_std_error": None, "per_part": {},
                      "design": "/x/<lens>", "command": "lensmount simulate"}, {"preview": png})
    assert "http:" not in doc and "https:" not in doc and "src=\"data:image/png;base64," in doc
    text = re.sub(r'data:image/png;base64,[^"]*', "", doc)
    assert not re.search(r"\b(nan|inf)\b", text, re.IGNORECASE)
    assert "—" in text  # the unknown error bar is shown as unknown
    assert "&lt;lens&gt;" in doc  # user text is escaped
