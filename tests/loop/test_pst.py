"""PST: angles parse, bad input is one paragraph; the reference design's PST falls by orders
of magnitude past the field edge, meets the analytic in-field value and agrees with `simulate` (slow)."""

import csv
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.loop.pst import PstOptions, parse_angles, pst
from lensmount.loop.pst_report import write_pst
from lensmount.cli import app
from lensmount.errors import InputError

DESIGN = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


def test_parse_angles():
    assert parse_angles("0:30:10") == [0, 10, 20, 30]
    assert parse_angles("0:1:0.25") == [0, 0.25, 0.5, 0.75, 1.0]
    assert parse_angles("7, 0,20") == [7, 0, 20]
    for bad in ("0:30:0", "30:0:1", "a,b", "", "0:95:5", "-1"):
        with pytest.raises(InputError):
            parse_angles(bad)


def test_bad_angles_are_one_paragraph_and_exit_2(tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["pst", str(DESIGN), "--scene", str(DESIGN / "scenes" / "case1-diaphragm-edge.toml"),
                                      "--angles", "0:30:-1", "--out", str(out)])
    assert result.exit_code == 2 and "--angles" in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_a_scene_is_named_as_simulate_names_it_and_an_unknown_name_lists_the_scenes(tmp_path):
    out = tmp_path / "out"
    named = CliRunner().invoke(app, ["pst", str(DESIGN), "--scene", "case1-diaphragm-edge", "--angles", "5",
                                     "--seed", "-1", "--out", str(out)])
    assert named.exit_code == 2 and "--seed" in named.output and "not found" not in named.output  # the name was read
    unknown = CliRunner().invoke(app, ["pst", str(DESIGN), "--scene", "case9", "--angles", "5", "--out", str(out)])
    text = " ".join(unknown.output.split())
    assert unknown.exit_code == 2 and "case1-diaphragm-edge" in text and "case2-lambertian" in text
    assert "Traceback" not in unknown.output and not out.exists()


def _small_scene(design: Path, direct: bool = True) -> Path:
    """Case 2 (every mount face Lambertian 5 %) with the direct image on (or not), a 30×30 detector, few photons."""
    text = (design / "scenes" / "case2-lambertian.toml").read_text()
    for old, new in (("pixels = [600, 600]", "pixels = [30, 30]"), ("direct = false", f"direct = {str(direct).lower()}"),
                     ("photons = 20_000", "photons = 10_000"), ("passes = 32", "passes = 8"),
                     ("view_map_pitch = 4", "view_map_pitch = 1"),
                     ("target_rel_error = 0.05", "")):
        assert old in text
        text = text.replace(old, new)
    path = design / "scenes" / "pst-small.toml"
    path.write_text(text)
    return path


def test_each_angle_reads_as_if_run_alone(tmp_path):
    """pst builds pass i's view map once and gathers every angle's photons of pass i at it. The
    invariant: each angle's PST and error bar are exactly those of `simulate` of that angle alone
    with the same seed (its own scene file, scene, tracer and view maps), while the angles differ."""
    from lensmount.loop.simulate import SimulateOptions, simulate
    from lensmount.physics.sources import entering_fraction

    design = tmp_path / "design"
    shutil.copytree(DESIGN, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    scene = _small_scene(design, direct=False)
    angles, seed, passes, photons = (0.0, 7.0, 20.0), 5, 3, 2_000
    result = pst(PstOptions(design, scene, angles, passes=passes, photons_per_pass=photons, seed=seed,
                            geometry=tmp_path / "geometry", workers=2))
    text = scene.read_text()
    for point in result.points:
        alone = design / "scenes" / f"alone-{point.angle_deg:g}.toml"
        alone.write_text(text.replace("off_axis_deg = 7.0", f"off_axis_deg = {point.angle_deg}"))
        run = simulate(SimulateOptions(design, alone, seed=seed, passes=passes, photons_per_pass=photons,
                                       geometry=tmp_path / "geometry", workers=1, record=False,
                                       out=tmp_path / f"alone-{point.angle_deg:g}"))
        s = run.summary
        # E_in / E_sun: the mean of cos over the 0.53° sun (1 − 5e-6 on axis), as pst divides by
        e_in = entering_fraction(point.angle_deg, math.radians(0.53) / 2)
        assert s["passes"] == point.passes == passes
        assert point.pst == pytest.approx(s["stray_flux_mm2"] / (44.5 * 44.5 * e_in), rel=1e-12, abs=0)
        if s["stray_flux_std_error_mm2"] is None:  # no error bar alone (a tail with no bound): none in the sweep
            assert point.std_error is None
        else:
            assert point.std_error == pytest.approx(s["stray_flux_std_error_mm2"] / (44.5 * 44.5 * e_in), rel=1e-9)
    values = sorted(p.pst for p in result.points)
    assert values[0] > 0 and values[1] > 1.5 * values[0] and values[2] > 1.5 * values[1]  # three different angles


@pytest.mark.slow
def test_pst_of_the_reference_design(tmp_path):
    from lensmount.loop.simulate import SimulateOptions, simulate
    from lensmount.optics.paraxial import paraxial
    from lensmount.design.folder import load_design

    design = tmp_path / "design"
    shutil.copytree(DESIGN, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    scene = _small_scene(design)
    result = pst(PstOptions(design, scene, (0.0, 7.0, 20.0)))
    by_angle = {p.angle_deg: p for p in result.points}
    assert result.field_edge_deg < 7.0 and by_angle[0.0].in_field and not by_angle[7.0].in_field

    # In the field the direct image carries everything the entrance pupil takes in (perfect AR
    # coatings, no vignetting on axis): PST(0) = π (EPD/2)² / detector area, plus a little stray light.
    epd = paraxial(load_design(design).prescription).epd
    expected = math.pi * (epd / 2) ** 2 / (44.5 * 44.5)
    p0 = by_angle[0.0]
    assert abs(p0.pst - expected) < 4 * p0.std_error + 0.01 * expected, (p0.pst, expected)

    # Past the field edge only stray light is left: orders of magnitude below.
    assert by_angle[7.0].pst < 1e-2 * p0.pst
    assert 0 < by_angle[20.0].pst < 1e-2 * by_angle[7.0].pst

    # The same value as `simulate` at 7° (its own geometry, scene and tracer; another seed).
    run = simulate(SimulateOptions(design, scene, seed=11, out=tmp_path / "sim7", workers=1, record=False))
    s = run.summary
    cos = math.cos(math.radians(7.0))
    sim, sim_se = s["mean_irradiance"] / cos, s["stray_flux_std_error_mm2"] / (44.5 * 44.5 * cos)
    p7 = by_angle[7.0]
    assert abs(p7.pst - sim) < 4 * math.hypot(p7.std_error, sim_se), (p7.pst, p7.std_error, sim, sim_se)

    paths = write_pst(tmp_path / "pst", result)
    rows = paths["csv"].read_text().splitlines()
    assert rows[0].startswith("angle_deg,pst,std_error") and len(rows) == 4
    assert paths["png"].read_bytes()[:4] == b"\x89PNG" and "data:image/png;base64," in paths["html"].read_text()


def test_no_light_entering_is_pst_zero_not_a_huge_number():
    from lensmount.loop.pst import pst_of
    from lensmount.physics.sources import CollimatedSource, EmissionDisc

    at_90 = CollimatedSource(90.0, 90.0, EmissionDisc((0.0, 0.0, 0.0), 1.0))
    assert at_90.entering_fraction == 0.0
    assert pst_of(1e-9, 1e-10, 100.0, at_90.entering_fraction) == (0.0, 0.0)
    value, _ = pst_of(2.0, 0.1, 100.0, 0.5)
    assert value == pytest.approx(2.0 / (100.0 * 0.5))


def test_angles_take_mixed_spacing_up_to_90():
    assert parse_angles("0:3:1,35:45:5") == [0, 1, 2, 3, 35, 40, 45]
    assert parse_angles("0,2,5,10") == [0, 2, 5, 10]
    assert parse_angles("80:90:5") == [80, 85, 90]
    assert parse_angles("0:2:1,2,1") == [0, 1, 2]  # each angle once
    for bad in ("0:30:1,95", "0:30:1,x", "0:30", ","):
        with pytest.raises(InputError):
            parse_angles(bad)


def test_a_requirement_is_log_linear_between_its_angles_and_refuses_unknown_keys():
    from lensmount.design.scene import RequirementSpec

    req = RequirementSpec(angles_deg=(0.0, 10.0, 30.0), pst_max=(1e-2, 1e-4, 1e-6))
    assert req.limit(5.0) == pytest.approx(1e-3) and req.limit(20.0) == pytest.approx(1e-5)
    assert req.limit(0.0) == pytest.approx(1e-2) and req.limit(31.0) is None
    for bad in ({"angles_deg": (0.0, 10.0), "pst_max": (1e-2,)}, {"angles_deg": (10.0, 0.0), "pst_max": (1, 1)},
                {"angles_deg": (0.0,), "pst_max": (0.0,)}, {"angles_deg": (0.0,), "pst_max": (1.0,), "pst": 1}):
        with pytest.raises(Exception):
            RequirementSpec(**bad)


def _requirement_run(tmp_path, limits: tuple[float, float], angles: str = "0,7", extra: str = ""):
    """`lensmount pst` with the forward method on the small scene (direct on, lossless glass) and [requirement] at
    0° and 7°."""
    design = tmp_path / "design"
    if not design.exists():
        shutil.copytree(DESIGN, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    scene = _small_scene(design)
    # lossless glass: on axis the PST is then the pupil's area over the detector's (`_on_axis_pst`)
    requirement = f"\n[requirement]\nangles_deg = [0.0, 7.0]\npst_max = [{limits[0]!r}, {limits[1]!r}]\n{extra}"
    scene.write_text(scene.read_text().replace("[effects]", "[effects]\nabsorption = false") + requirement)
    out = tmp_path / f"out-{limits[0]:.4g}"
    result = CliRunner().invoke(app, ["pst", str(design), "--scene", str(scene), "--angles", angles, "--method",
                                      "forward", "--passes", "4", "--photons-per-pass", "5000", "--seed", "3",
                                      "--workers", "1", "--out", str(out)])
    return result, out


def _on_axis_pst() -> float:
    """PST on axis, in the field: the entrance pupil's area over the detector's (perfect AR, no vignetting)."""
    from lensmount.design.folder import load_design
    from lensmount.optics.paraxial import paraxial

    epd = paraxial(load_design(DESIGN).prescription).epd
    return math.pi * (epd / 2) ** 2 / (44.5 * 44.5)


def test_a_curve_over_its_requirement_by_30_percent_at_one_angle_exits_1_naming_it(tmp_path):
    """On axis the forward PST is the pupil's area over the detector's; a requirement 1/1.3 of that at 0° is
    exceeded there (exit 1, 0° named), one 1.3 times it is met (exit 0). Past the field (7°) the requirement is
    the on-axis value: met either way."""
    expected = _on_axis_pst()
    result, out = _requirement_run(tmp_path, (expected / 1.3, expected))
    assert result.exit_code == 1, result.output
    assert "exceeds the requirement at 99 % confidence at 0°" in result.output and "7° (" not in result.output
    rows = (out / "pst.csv").read_text().splitlines()
    assert rows[0].startswith("angle_deg,pst,std_error") and rows[1].split(",")[10] == "exceeds"
    result, out = _requirement_run(tmp_path, (expected * 1.3, expected))
    assert result.exit_code == 0, result.output
    assert "meets the requirement" in result.output and "the sweep ≤" in result.output
    assert [r.split(",")[10] for r in (out / "pst.csv").read_text().splitlines()[1:]] == ["inside", "inside"]
    assert (out / "pst.png").read_bytes()[:4] == b"\x89PNG"


def test_an_unknown_requirement_key_is_refused_with_exit_2(tmp_path):
    result, out = _requirement_run(tmp_path, (1.0, 1.0), extra="limit_db = 3\n")
    assert result.exit_code == 2 and "limit_db" in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_an_angle_where_nothing_reaches_the_detector_reads_zero_below_its_upper_bound_and_says_why(tmp_path):
    """Scatter off, direct off: nothing can reach the detector past the field. The point reads 0 with the rule of
    three's bound (3 photons' flux over the passes, in PST), std_error blank with the reason in pst.csv."""
    design = tmp_path / "design"
    shutil.copytree(DESIGN, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    scene = _small_scene(design, direct=False)
    text = scene.read_text()
    start = text.index("scatter =")
    scene.write_text(text[:start] + "scatter = false\n" + text[text.index("\n", start) + 1:])
    result = pst(PstOptions(design, scene, (20.0,), method="forward", passes=3, photons_per_pass=2000, seed=1,
                            geometry=tmp_path / "geometry", workers=1))
    p = result.points[0]
    assert p.pst == 0 and p.std_error is None and "no light reached the detector" in p.reason
    # by hand: 3 photons of flux A_S / N (the sun's emission disc over the photons of a pass) over 3 passes, in PST
    from lensmount.loop.prepare import build, read_inputs
    from lensmount.scene.build import make_source
    from lensmount.physics.sampler import Streams

    d, spec = read_inputs(design, scene)
    base = build(d, spec, tmp_path / "geometry").scene
    source = make_source(spec.source.model_copy(update={"off_axis_deg": 20.0}), base.front_opening, base.mesh,
                         base.detector, d.prescription)
    rays, _ = source.emit(2000, Streams(1, "check", np.arange(2000)))
    photon = float(rays.weight[rays.alive].max())  # A_S / N: every photon of a sun carries the same flux
    assert p.upper_bound == pytest.approx(3 * photon / 3 / (44.5 * 44.5 * source.entering_fraction), rel=1e-6)
    rows = write_pst(tmp_path / "pst", result)["csv"].read_text().splitlines()
    header, row = rows[0].split(","), next(csv.reader(rows[1:]))
    assert row[header.index("std_error")] == "" and row[header.index("reason")].startswith("no light reached")
    assert float(row[header.index("upper_bound_95")]) == pytest.approx(p.upper_bound, rel=1e-5)


@pytest.mark.slow
def test_forward_seeds_on_the_cooke_triplet_quote_errors_that_match_their_spread(tmp_path):
    """The Cooke triplet's case-2 scene (every face Lambertian 5 %) at 35°, forward: a photon's flux is bounded by
    its emitted flux × 0.05 (one bounce), so every seed gets the batch-means error bar, no pass is called dominant
    for the Poisson skew of a few one-bounce photons, the seeds spread as much as they quote (within the noise of
    six spreads of 8 passes), and each seed's 2σ interval holds the other seeds' mean in at least 5 of 6."""
    cooke = DESIGN.parent / "cooke-triplet"
    runs = [pst(PstOptions(cooke, cooke / "scenes" / "case2-lambertian.toml", (35.0,), method="forward", passes=8,
                           photons_per_pass=100_000, seed=seed, workers=1, geometry=tmp_path / "geometry")).points[0]
            for seed in range(1, 7)]
    assert all(p.std_error is not None and not p.heavy and p.reason == "" for p in runs), [p.reason for p in runs]
    values, quoted = np.array([p.pst for p in runs]), np.array([p.std_error for p in runs])
    assert 0.5 < np.std(values, ddof=1) / quoted.mean() < 1.7, (values, quoted)
    held = [abs(values[k] - np.delete(values, k).mean()) <= 2 * math.hypot(quoted[k], np.delete(quoted, k).mean()
                                                                          / math.sqrt(5)) for k in range(6)]
    assert sum(held) >= 5


def _curve(tmp_path, name: str, values: dict) -> Path:
    """A pst folder whose points are {angle: (pst, std_error or None, upper bound or None)}, 16 passes each."""
    from lensmount.loop.pst import PstPoint, PstResult

    points = [PstPoint(a, v, se, a < 8, 16, 160_000, 1.0, upper_bound=ub) for a, (v, se, ub) in values.items()]
    write_pst(tmp_path / name, PstResult(points, 8.0, 90.0, "bidirectional", ["scatter"], {}))
    return tmp_path / name


def test_compare_of_two_pst_curves_names_the_angles_that_regressed(tmp_path):
    """A revision that doubles the PST at 20° (errors 2 %) and leaves 10° as it was (0.5 %): compare says regression at
    20° alone and exits 1; against itself, exit 0. A zero reading (below its bound) that becomes a clear value
    far above the bound is a regression too; one that stays below it decides nothing."""
    old = _curve(tmp_path, "old", {10.0: (1e-3, 5e-6, None), 20.0: (1e-5, 2e-7, None), 60.0: (0.0, None, 1e-9)})
    new = _curve(tmp_path, "new", {10.0: (1e-3, 5e-6, None), 20.0: (2e-5, 4e-7, None), 60.0: (1e-6, 2e-8, None)})
    result = CliRunner().invoke(app, ["compare", str(old), str(new)])
    assert result.exit_code == 1, result.output
    assert "regression at 20°, 60°" in result.output
    lines = {line.split("°")[0].strip(): line for line in result.output.splitlines() if "PST" in line}
    assert "no regression" in lines["10"] and "regression" in lines["20"]
    same = CliRunner().invoke(app, ["compare", str(old), str(old)])
    assert same.exit_code == 0 and "no angle regressed" in same.output
