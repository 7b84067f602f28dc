"""Path signatures (integrators.paths) and their sums over passes (analysis.paths) on tiny synthetic data.

References are written here independently: plain Python sums over the deposits, numpy's
sample standard deviation over the per-pass series, block sums of dense images.
"""

import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.analysis.error_bar import t_factor  # noqa: E402
from lensmount.analysis.passes import Accumulator  # noqa: E402
from lensmount.analysis.paths import PathSums, signature_from_hex, top_paths  # noqa: E402
from lensmount.mesh import FaceTag  # noqa: E402
from lensmount.integrators.estimate import PassEstimate  # noqa: E402
from lensmount.integrators.paths import EMPTY, FaceTally, PathTally, ghost_code, ghost_of, signature_of  # noqa: E402


def _sig(codes):
    s = np.array([EMPTY], np.int64)
    for c in codes:
        s = signature_of(s, np.array([c]))
    return int(s[0])


def test_signature_is_ordered_nonzero_and_collision_free_on_all_short_paths():
    assert _sig([3, 7]) != _sig([7, 3])
    assert _sig([3]) != _sig([3, 3])
    assert _sig([-2]) != _sig([2])  # a ghost stretch is not the face with the same number
    codes = np.arange(-4, 150)
    one = signature_of(np.zeros(len(codes), np.int64), codes)
    two = signature_of(np.repeat(one, len(codes)), np.tile(codes, len(codes)))
    sigs = set(one.tolist()) | set(two.tolist())
    assert len(sigs) == len(codes) ** 2 + len(codes)
    assert EMPTY not in sigs
    # vectorised equals one at a time
    parent = np.array([_sig([1]), _sig([2]), EMPTY], np.int64)
    assert signature_of(parent, np.array([5, 5, 5])).tolist() == [_sig([1, 5]), _sig([2, 5]), _sig([5])]


def test_tally_records_events_and_sums_flux_and_binned_images():
    shape, area = (4, 6), 0.5
    tally = PathTally(shape, area, max_side=3)  # block 2: a 2 × 3 binned image
    assert tally.block == 2
    a = tally.extend(np.zeros(3, np.int64), np.array([4, 4, 9]))
    g = ghost_code(np.array([2, 2]), np.array([5, 5]), np.array([2, 2]))
    b = tally.extend(a[:2], g)
    assert tally.events[int(a[0])] == (4,) and tally.events[int(b[0])] == (4, int(g[0]))
    assert ghost_of(int(g[0])) == (2, 5, 2) and ghost_of(int(ghost_code([1], [0], [-1])[0])) == (1, 0, -1)
    rng = np.random.default_rng(0)
    sig = rng.choice(np.array([a[0], a[2], b[0]]), 500)
    pixel = rng.integers(0, 24, 500)
    value = rng.random(500)
    tally.add(sig[:200], pixel[:200], value[:200])
    tally.add(sig[200:], pixel[200:], value[200:])
    out = tally.finish()
    flux = defaultdict(float)
    dense = defaultdict(lambda: np.zeros(shape))
    for s, p, v in zip(sig.tolist(), pixel.tolist(), value.tolist()):
        flux[s] += v * area
        dense[s][p // 6, p % 6] += v
    assert sorted(out.signature.tolist()) == sorted(flux)
    for s, f in zip(out.signature.tolist(), out.flux):
        assert f == pytest.approx(flux[s], rel=1e-12)
        sel = out.image_signature == s
        binned = np.zeros(6)
        np.add.at(binned, out.image_pixel[sel], out.image_value[sel])
        expect = dense[s].reshape(2, 2, 3, 2).sum(axis=(1, 3)).ravel()
        assert np.allclose(binned, expect)


def _pass(shape, flux_by_codes, n_tags=3, lit=None):
    tally = PathTally(shape, 1.0)
    for codes, f in flux_by_codes.items():
        s = np.zeros(1, np.int64)
        for c in codes:
            s = tally.extend(s, np.array([c]))
        tally.add(s, np.array([0]), np.array([f]))
    faces = FaceTally(n_tags, shape, 1.0, tally.block)
    faces.add_lit(np.arange(n_tags), np.ones(n_tags) if lit is None else lit)
    faces.add_seen(np.array([1]), np.array([0]), np.array([0.5]))
    image = np.zeros(shape)
    image[0, 0] = sum(flux_by_codes.values())
    return PassEstimate(image=image, per_part=image[None], part_names=["all"], pixel_area_mm2=1.0, photons=10,
                        paths=tally.finish(), faces=faces.finish())


PASSES = [{(0,): 1.0, (0, 1): 0.5}, {(0,): 2.0, (2,): 0.25}, {(0,): 1.5, (0, 1): 0.1, (2,): 0.05},
          {(0,): 1.2}]


def test_sums_over_passes_give_the_mean_and_the_spread_of_each_path(tmp_path):
    shape = (2, 2)
    acc = Accumulator.empty(shape, ["all"], 1.0)
    for p in PASSES:
        acc.add(_pass(shape, p))
    tags = [FaceTag(f"part-{k}", "spacer", "mount", "black", face=k) for k in range(3)]
    report = top_paths(acc.paths, tags, aperture_flux_mm2=10.0, top=2)
    for codes in ((0,), (0, 1), (2,)):
        series = np.array([p.get(codes, 0.0) for p in PASSES])
        s = acc.paths.signature.tolist().index(_sig(codes))
        assert acc.paths.mean_flux()[s] == pytest.approx(series.mean())
        assert acc.paths.std_error()[s] == pytest.approx(np.std(series, ddof=1) / 2 * t_factor(4))
    first, second = report["paths"]
    assert [e["part"] for e in first["events"]] == ["part-0"]
    assert [e["part"] for e in second["events"]] == ["part-0", "part-1"]
    assert signature_from_hex(second["signature"]) == _sig((0, 1))
    assert first["fraction"] == pytest.approx(np.mean([1.0, 2.0, 1.5, 1.2]) / 10)
    listed = sum(r["fraction"] for r in report["paths"]) + report["other"]["fraction"]
    assert listed == pytest.approx(acc.flux / 10) == pytest.approx(report["total_fraction"])
    # the run's report.html shows them
    from lensmount.run.report import run_report

    html = run_report({"top_paths": report}, {})
    assert "part-0 face 0 (mount) → part-1 face 1 (mount)" in html and "1 other paths" in html
    # the checkpoint keeps all of it
    acc.save(tmp_path / "c.npz")
    back, _ = Accumulator.load(tmp_path / "c.npz")
    assert back.paths.signature.tolist() == acc.paths.signature.tolist()
    assert np.array_equal(back.paths.total_sq, acc.paths.total_sq)
    assert back.paths.events == acc.paths.events
    assert np.array_equal(back.paths.images, acc.paths.images)
    assert back.paths.seen.tolist() == [0.0, 2.0, 0.0] and back.paths.lit.tolist() == [4.0] * 3


def test_a_path_image_is_the_mean_over_the_passes_it_was_kept(monkeypatch):
    import lensmount.analysis.paths as paths

    monkeypatch.setattr(paths, "KEPT_IMAGES", 1)
    sums = PathSums()
    shape = (1, 1)
    for p in ({(0,): 1.0, (1,): 0.5}, {(1,): 3.0}, {(1,): 1.0, (0,): 1.0}):
        e = _pass(shape, p)
        sums.add(e.paths, e.faces)
    # (0,) led after pass 1, (1,) from pass 2 on: its image is the mean of passes 2 and 3
    assert sums.image_signature.tolist() == [_sig((1,))]
    assert sums.path_image(_sig((1,)))[0, 0] == pytest.approx((3.0 + 1.0) / 2)
    assert sums.path_image(_sig((0,))) is None


def test_an_old_checkpoint_is_refused_with_its_version(tmp_path):
    acc = Accumulator.empty((2, 2), ["all"], 1.0)
    acc.add(_pass((2, 2), PASSES[0]))
    acc.save(tmp_path / "c.npz")
    with np.load(tmp_path / "c.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["version"] = np.int64(5)
    np.savez(tmp_path / "old.npz", **arrays)
    with pytest.raises(ValueError, match="version 5"):
        Accumulator.load(tmp_path / "old.npz")
    assert not math.isnan(acc.flux)


def test_a_singlet_ghost_is_named_by_its_surface_pair_and_fills_the_ghosts_channel():
    """Uncoated singlet, black barrel, sun on axis: the only two-reflection ghost reaching the
    detector reflects at surface 2 (back toward the sun), then at surface 1 (1-based)."""
    from lensmount.integrators.forward import forward_pass
    from lensmount.physics.bsdf import make_bsdf
    from lensmount.trace.tracer import Tracer

    scene = singlet_barrel(make_bsdf("absorber"), off_axis_deg=0.0, ghosts=True, coating="uncoated", detector_mm=40.0)
    est = forward_pass(scene, Tracer(scene), 50_000, 3, 0)
    paths = est.paths
    ghosts = est.part_flux[est.part_names.index("ghosts")]
    assert ghosts > 0
    tags = list(scene.mesh.tag_table)
    from lensmount.analysis.paths import describe_event

    named = {tuple(describe_event(c, tags)["name"] for c in paths.events[int(s)]): f
             for s, f in zip(paths.signature, paths.flux)}
    assert named == {("ghost S2–S1",): pytest.approx(ghosts, rel=1e-12)}


def test_faces_rank_critical_and_illuminated_by_etendue_times_irradiance_and_say_nothing_without_a_view_map():
    from lensmount.analysis.paths import face_report
    from lensmount.integrators.paths import PassFaces

    tags = [FaceTag(f"part-{k}", "spacer", "mount", "black", face=k) for k in range(4)]
    areas = np.array([1.0, 2.0, 4.0, 1.0])
    # lit flux 1, 1, 0, 3 (irradiance 1, 0.5, 0, 3); étendue 0.2, 1.0, 0.5, 0 (mm² sr)
    lit, seen = np.array([1.0, 1.0, 0.0, 3.0]), np.array([0.2, 1.0, 0.5, 0.0])
    sums = PathSums()
    tally = PathTally((1, 1), 1.0)
    for _ in range(2):
        sums.add(tally.finish(), PassFaces(lit, seen, np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)))
    report = face_report(sums, tags, areas, aperture_flux_mm2=1.0)
    both = report["critical_and_illuminated"]
    assert [r["part"] for r in both] == ["part-1", "part-0"]  # G·E/π: 0.5/π > 0.2/π
    assert both[0]["product_mm2"] == pytest.approx(1.0 * 0.5 / math.pi)
    assert [r["part"] for r in report["critical_unlit"]] == ["part-2"]
    assert [r["part"] for r in report["lit_not_critical"]] == ["part-3"]
    forward = PathSums()
    forward.add(tally.finish(), PassFaces(lit))
    report = face_report(forward, tags, areas, aperture_flux_mm2=1.0)
    assert not report["view_map"] and not any(report[k] for k in ("critical_and_illuminated", "critical_unlit",
                                                                  "lit_not_critical"))
