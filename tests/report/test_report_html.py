"""report.html opens offline in headless Chromium with every image loaded and the verdict shown."""

import numpy as np

from lensmount.analysis.passes import Accumulator
from lensmount.integrators.estimate import PassEstimate
from lensmount.run.report import comparison_report, write_report
from lensmount.run.results import shared_scale, write_difference, write_preview, write_run

from .conftest import images_loaded


def _run(level: float, seed: int) -> Accumulator:
    acc = Accumulator.empty((12, 16), ["diaphragm", "barrel"], 0.01)
    rng = np.random.default_rng(seed)
    for _ in range(4):
        img = level * rng.random((12, 16))
        acc.add(PassEstimate(img, np.stack([0.3 * img, 0.7 * img]), acc.part_names, 0.01, 100))
    return acc


SUMMARY = {"method": "bidirectional", "passes": 4, "photons": 400, "time_s": 1.5, "stray_fraction": 1.504e-6,
           "stray_fraction_std_error": 1.3e-7, "stray_fraction_rel_error": 0.086, "stray_fraction_bias_bound": 4e-8,
           "per_part": {"diaphragm": {"fraction": 1.0e-6, "std_error": 1e-7, "bias_bound": 3e-8},
                        "barrel": {"fraction": 5.04e-7, "std_error": 5e-8, "bias_bound": 1e-8}},
           "input_hash": "a1b2c3d4e5f60718",
           "provenance": {"design_name": "mylens", "scene_name": "case1", "lens_sha256": "11aa", "mount_sha256": "22bb",
                          "scene_sha256": "33cc", "git_commit": "0123456789abcdef0123456789abcdef01234567",
                          "git_dirty": False}}


def test_run_report_opens_offline_with_images_and_provenance(tmp_path, open_offline):
    paths = write_run(tmp_path / "run", _run(1e-3, 0), SUMMARY, extent_mm=(-8, 8, -6, 6))
    page, requested = open_offline(paths["html"])
    widths = images_loaded(page)
    assert widths and all(w > 0 for w in widths), widths
    text = page.inner_text("body")
    for shown in ("1.504e-06 ± 1.3e-07", "bias bound", "diaphragm", "a1b2c3d4e5f60718",
                  "0123456789abcdef0123456789abcdef01234567",
                  "provenance.mount_sha256", "mylens · case1"):
        assert shown in text, shown
    assert [u for u in requested if not u.startswith(("file:", "data:"))] == []


def test_comparison_report_shows_the_verdict_and_both_images(tmp_path, open_offline):
    old, new = _run(1e-3, 1), _run(3e-3, 2)
    scale = shared_scale([(old.mean_image, old.std_error_image), (new.mean_image, new.std_error_image)])
    extent = (-8, 8, -6, 6)
    for name, acc in (("old", old), ("new", new)):
        write_preview(tmp_path / f"{name}.png", acc.mean_image, extent, title=name, scale=scale)
    write_difference(tmp_path / "diff.png", new.mean_image, old.mean_image, extent, scale)
    verdict = "regression: stray fraction +205 % ± 24 % at 99 % confidence"
    doc = comparison_report(SUMMARY, {**SUMMARY, "stray_fraction": 4.59e-6}, verdict,
                            [["total", "1.504e-06", "4.59e-06", "+205 % ± 24 %"]],
                            ["", "old", "new", "change"],
                            {n: tmp_path / f"{n}.png" for n in ("old", "new", "diff")}, kind="regression")
    page, requested = open_offline(write_report(tmp_path / "report.html", doc))
    assert page.inner_text("#verdict") == verdict
    widths = images_loaded(page)
    assert len(widths) == 3 and all(w > 0 for w in widths), widths
    assert [u for u in requested if not u.startswith(("file:", "data:"))] == []


def test_the_browser_check_sees_a_broken_image_and_a_network_fetch(tmp_path, open_offline):
    """The two checks above can fail: a corrupt inline PNG reads width 0, a CDN link is caught."""
    page_file = tmp_path / "bad.html"
    page_file.write_text('<html><body><img src="data:image/png;base64,AAAA">'
                         '<img src="https://cdn.example.com/x.png"></body></html>')
    page, requested = open_offline(page_file)
    assert images_loaded(page) == [0, 0]
    assert "https://cdn.example.com/x.png" in requested


def test_compare_writes_a_report_with_the_verdict_and_shared_scale_images(tmp_path, open_offline):
    """loop.compare on two results folders: report.html carries its verdict; old/new previews
    share one colour scale and binning (results.shared_scale)."""
    from lensmount.loop.compare import CompareOptions, compare
    from lensmount.loop.compare import verdict_sentence
    from lensmount.run.results import write_run as write_results

    old, new = _run(1e-3, 1), _run(3e-3, 2)
    for name, acc in (("old", old), ("new", new)):
        s = {**SUMMARY, "stray_fraction": acc.flux * 1e-3, "stray_fraction_std_error": acc.flux_std_error * 1e-3,
             "stray_flux_mm2": acc.flux, "stray_flux_std_error_mm2": acc.flux_std_error}
        write_results(tmp_path / name, acc, s, extent_mm=(-8, 8, -6, 6))
    result = compare(CompareOptions(tmp_path / "old", tmp_path / "new", out=tmp_path / "cmp"))
    assert result.verdict.verdict == "regression"
    page, requested = open_offline(result.paths["html"])
    assert page.inner_text("#verdict") == verdict_sentence(result.verdict)
    assert page.inner_text("#verdict").startswith("regression")
    widths = images_loaded(page)
    assert len(widths) == 3 and all(w > 0 for w in widths), widths
    assert [u for u in requested if not u.startswith(("file:", "data:"))] == []


def test_comparison_report_fits_1400_px_and_marks_what_differs(tmp_path, open_offline):
    """The provenance table fits 1400 px (64-digit hashes, long paths and command lines wrap instead of
    pushing the "new" column off screen) and marks the fields that differ. A
    1400 px screenshot is kept for a reader; the check is that nothing overflows sideways."""
    from .conftest import horizontal_overflow

    long_path = "/home/engineer/projects/" + "optics-group-" * 8 + "mylens"
    def prov(mount_sha, commit):
        return {**SUMMARY["provenance"], "design_path": long_path, "scene_path": long_path + "/scenes/case1.toml",
                "mount_sha256": mount_sha, "lens_sha256": "ab" * 32, "git_commit": commit,
                "command_line": "lensmount simulate " + long_path + " --scene " + long_path + "/scenes/case1.toml "
                                "--out " + long_path + "/runs/case1-after-the-vane-change --passes 32 --seed 7"}
    old = {**SUMMARY, "provenance": prov("cd" * 32, "0" * 40), "input_hash": "f" * 16}
    new = {**SUMMARY, "provenance": prov("ef" * 32, "1" * 40), "input_hash": "e" * 16}
    doc = comparison_report(old, new, "no regression: change +1e-08", [["total", "1.5e-06", "1.51e-06", "+1e-08"]],
                            ["", "old", "new", "change"], {})
    page, _ = open_offline(write_report(tmp_path / "report.html", doc))
    page.screenshot(path=str(tmp_path / "report-1400.png"), full_page=True)
    assert page.evaluate("window.innerWidth") == 1400
    assert horizontal_overflow(page) <= 0
    last = page.evaluate("Math.max(...Array.from(document.querySelectorAll('td')).map(c => c.getBoundingClientRect().right))")
    assert last <= 1400
    marked = page.evaluate("Array.from(document.querySelectorAll('tr.differs td:first-child')).map(c => c.innerText)")
    assert sorted(marked) == ["≠ input_hash", "≠ provenance.git_commit",
                              "≠ provenance.mount_sha256"], marked


def test_the_overflow_check_sees_a_page_wider_than_the_window(tmp_path, open_offline):
    from .conftest import horizontal_overflow

    wide = tmp_path / "wide.html"
    wide.write_text("<html><body><table><tr><td>" + "x" * 400 + "</td></tr></table></body></html>")
    page, _ = open_offline(wide)
    assert horizontal_overflow(page) > 0


def test_watch_page_headers_break_only_between_words(tmp_path, open_offline):
    """Long verdicts and file lists squeeze the other columns; a header may wrap between its words, never
    inside one ("seco / nds")."""
    from lensmount.loop.watch import Revision, write_watch_page

    history = [Revision(0, (), None, None, 90.0)] + [
        Revision(k, ("mount.toml", "finishes.toml", "templates/a-very-long-user-template-name.py"), None,
                 "the hood's length_mm = -4.0 is out of range " * 6, 12.5) for k in range(1, 4)]
    page, _ = open_offline(write_watch_page(tmp_path, tmp_path / "design", None, history))
    cut = page.evaluate("""() => Array.from(document.querySelectorAll('th')).filter(th => {
        const probe = document.createElement('span');
        probe.style.font = getComputedStyle(th).font;
        probe.style.whiteSpace = 'nowrap';
        document.body.appendChild(probe);
        const widest = Math.max(...th.innerText.split(/\\s+/).map(w => { probe.textContent = w;
                                                                         return probe.getBoundingClientRect().width; }));
        probe.remove();
        const style = getComputedStyle(th);
        const room = th.clientWidth - parseFloat(style.paddingLeft) - parseFloat(style.paddingRight);
        return room + 0.5 < widest;
    }).map(th => th.innerText)""")
    assert cut == [], cut
