"""PST: angles parse, bad input is one paragraph; the reference design's PST falls by orders
of magnitude past the field edge, meets the analytic in-field value and agrees with `simulate` (slow)."""

import math
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lensmount.loop.pst import PstOptions, parse_angles, pst, write_pst
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
