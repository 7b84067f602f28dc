"""Finite conjugates through the loop: inspect, init, regenerate, simulate a point source on the object plane.

The lens is the example Cooke triplet (f = 50 mm) with its object moved to 500 mm and its fields
given as object heights (0, 120, 170 mm), refocused to the paraxial conjugate: a file a user would
get from a vendor for a finite-conjugate use. US05831776 (tests/optics/corpus, a 248 nm lithography
lens with its object 111 mm in front, object-space NA) is the corpus's finite-conjugate file.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
import tomli_w
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.lens import load_lens
from lensmount.optics.io.zemax import read_zmx
from lensmount.optics.paraxial import paraxial
from tests.cad.test_init_lens import check_corpus_design

ROOT = Path(__file__).resolve().parents[2]
COOKE = ROOT / "examples" / "cooke-triplet" / "cooke-triplet.zmx"
CORPUS = ROOT / "tests" / "optics" / "corpus"
US05831776 = CORPUS / "US05831776-1.zmx"
# every finite-conjugate lens of the corpus (its object at a finite distance), found by reading the files
FINITE_CORPUS = [p for p in sorted(CORPUS.glob("*.zmx")) if read_zmx(p).finite_object]
SMALL_FINITE = CORPUS / "thorlabs-MAP105050-A.zmx"   # a matched achromat pair: 12 parts
D, HEIGHTS = 500.0, (0.0, 120.0, 170.0)


def _finite_cooke(folder: Path) -> Path:
    """The example Cooke triplet with its object at D, fields as object heights, image refocused."""
    from lensmount.optics.paraxial import paraxial

    text = COOKE.read_text()
    text = (text.replace("FTYP 0 0 3 3 0 0 0", "FTYP 1 0 3 3 0 0 0")
                .replace("YFLN 0 1.4E+1 2.0E+1", "YFLN 0 1.2E+2 1.7E+2")
                .replace("  DISZ INFINITY", f"  DISZ {D}", 1))
    path = folder / "cooke-500mm.zmx"
    path.write_text(text)
    p = load_lens(path)
    back = p.surfaces[-1].thickness + paraxial(p).image_z - p.image_z
    path.write_text(text.replace("  DISZ 42.20778", f"  DISZ {back:.6f}"))
    return path


@pytest.mark.slow
def test_the_beam_envelope_of_a_finite_object_closes_on_the_object_points(tmp_path):
    """The mount's beam comes from the object points: at the object plane the envelope is the
    largest object height, and it narrows toward the lens along straight lines."""
    from lensmount.optics.apertures import beam_envelope

    p = load_lens(_finite_cooke(tmp_path))
    assert p.object_distance == D and p.object_heights_mm == HEIGHTS
    r = beam_envelope(p, np.array([-D, -0.5 * D, -0.01]))
    assert r[0] == pytest.approx(max(HEIGHTS), abs=1e-6)
    assert r[0] > r[1] > r[2] and r[1] == pytest.approx(0.5 * (r[0] + r[2]), rel=0.02)


def _chain(lens: Path, tmp_path: Path, point_height: float, photons: int = 20000,
           scenes=("case2-lambertian", "object-lambertian")) -> dict:
    """inspect → init → regenerate → simulate a point source on the object plane (tiny budget), then
    init's `scenes`."""
    runner = CliRunner()
    shown = runner.invoke(app, ["inspect", str(lens)])
    assert shown.exit_code == 0, shown.output
    assert "in front of surface 1" in shown.output and "object heights" in shown.output
    design = tmp_path / "design"
    made = runner.invoke(app, ["init", str(design), "--lens", str(lens)])
    assert made.exit_code == 0, made.output
    reg = runner.invoke(app, ["regenerate", str(design), "--quiet"])
    assert reg.exit_code == 0, reg.output
    manifest = json.loads((design / "build" / "manifest.json").read_text())
    assert len(manifest["parts"]) >= 2
    case2 = tomllib.loads((design / "scenes" / "case2-lambertian.toml").read_text())
    w, h = case2["detector"]["width_mm"], case2["detector"]["height_mm"]
    scene = design / "scenes" / "object-point.toml"
    scene.write_text(f'description = "a point on the object plane"\n[source]\ntype = "point"\n'
                     f"height_mm = {point_height}\n[detector]\nwidth_mm = {w}\nheight_mm = {h}\n"
                     "pixels = [36, 24]\n[effects]\ndirect = true\n")
    out = tmp_path / "run"
    sim = runner.invoke(app, ["simulate", str(design), "--scene", str(scene), "--photons-per-pass", str(photons),
                              "--passes", "2", "--workers", "1", "--method", "forward", "--out", str(out)])
    assert sim.exit_code == 0, sim.output
    summary = json.loads((out / "summary.json").read_text())
    for name in scenes:  # init's scenes: the sun, and the object itself
        run = runner.invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / f"{name}.toml"),
                                  "--photons-per-pass", "2000", "--passes", "2", "--workers", "1",
                                  "--out", str(tmp_path / name)])
        assert run.exit_code == 0, run.output
        done = json.loads((tmp_path / name / "summary.json").read_text())
        assert math.isfinite(done["stray_fraction"]), name
    pst = runner.invoke(app, ["pst", str(design), "--scene", str(scene), "--angles", "0:10:5"])
    assert pst.exit_code == 2 and "source at infinity" in pst.output, pst.output  # one paragraph, no build
    return summary


@pytest.mark.slow
def test_a_finite_conjugate_lens_inspects_regenerates_and_images_a_point_on_its_object_plane(tmp_path):
    summary = _chain(_finite_cooke(tmp_path), tmp_path, point_height=80.0)
    direct = summary["per_part"]["direct"]["fraction"]
    assert summary["units"]["irradiance"].startswith("E/E_ref")
    # Normalised to the flux the lens accepts from the point (its paraxial entrance pupil): nearly all of
    # it reaches the image (the real pupil of a 9° field differs from the paraxial one by a few %).
    print(f"direct fraction {direct:.4f}, stray fraction {summary['stray_fraction']:.4g}")
    assert 0.85 < direct < 1.1
    assert math.isfinite(summary["stray_fraction"])


@pytest.mark.slow
def test_us05831776_inspects_regenerates_and_simulates(tmp_path):
    shown = CliRunner().invoke(app, ["inspect", str(US05831776)])   # imports: element 8 and two air gaps clipped
    assert shown.exit_code == 0 and "clipped" in shown.output, shown.output
    # init's scenes of this 45-part mount take ~25 s each: case 2 is simulated by the corpus checks below,
    # the object scene by the finite Cooke triplet above
    summary = _chain(US05831776, tmp_path, point_height=30.0, photons=5000, scenes=())
    assert math.isfinite(summary["stray_fraction"])
    notes = json.loads((tmp_path / "design" / "build" / "manifest.json").read_text())["notes"]
    for said in (notes, summary["warnings"]):   # the clips ride with the result: regenerate's and simulate's
        assert [w.split(" are edged")[0] for w in said if w.startswith("lens: ")] == [
            "lens: surfaces 15 and 16", "lens: surfaces 24 and 25", "lens: surfaces 28 and 29"]
    # The corpus's checks of every refractive lens (tests/cad/test_init_lens.py leaves this one to this test:
    # its init and 45-part regenerate once, not twice)
    check_corpus_design(tmp_path / "design", tmp_path / "case2")


def test_the_corpus_holds_finite_conjugate_lenses_of_both_object_spaces():
    """What the tests below run on: a finite object seen through an entrance pupil (the achromat pair) and
    in telecentric object space (US05831776)."""
    assert {p.name for p in FINITE_CORPUS} >= {SMALL_FINITE.name, US05831776.name}


def test_init_gives_a_finite_object_object_sources_not_the_sun(tmp_path):
    """For a finite object init's scenes light the object plane: case 2 is a point on it at the exclusion
    angle seen from the paraxial entrance pupil (as the file's field angles are), outside the object field;
    the object scene is the field itself, a Lambertian disc, its direct image on."""
    made = CliRunner().invoke(app, ["init", str(tmp_path / "d"), "--lens", str(SMALL_FINITE)])
    assert made.exit_code == 0, made.output
    assert "case2-lambertian.toml and scenes/object-lambertian.toml" in made.output
    p = load_lens(SMALL_FINITE)
    mount = tomllib.loads((tmp_path / "d" / "mount.toml").read_text())
    case2 = tomllib.loads((tmp_path / "d" / "scenes" / "case2-lambertian.toml").read_text())
    obj = tomllib.loads((tmp_path / "d" / "scenes" / "object-lambertian.toml").read_text())
    assert case2["source"]["type"] == "point" and not case2["effects"]["direct"]
    to_pupil = p.object_distance + paraxial(p).entrance_pupil_z
    seen = math.degrees(math.atan(case2["source"]["height_mm"] / to_pupil))
    assert seen == pytest.approx(mount["hood"]["exclusion_deg"], abs=0.01)
    assert case2["source"]["height_mm"] > max(p.object_heights_mm)
    assert obj["source"] == {"type": "disc", "radius_mm": pytest.approx(max(p.object_heights_mm), abs=1e-3)}
    assert obj["effects"]["direct"] and obj["detector"] == case2["detector"]


def _simulate(design: Path, scene: Path, out: Path, photons: int, method: str = "bidirectional") -> dict:
    doc = tomllib.loads(scene.read_text())
    doc["detector"]["pixels"] = [max(1, n // 10) for n in doc["detector"]["pixels"]]
    scene.write_text(tomli_w.dumps(doc))
    run = CliRunner().invoke(app, ["simulate", str(design), "--scene", str(scene), "--photons-per-pass", str(photons),
                                   "--passes", "8", "--workers", "1", "--method", method, "--out", str(out)])
    assert run.exit_code == 0 and run.exception is None, run.output
    return json.loads((out / "summary.json").read_text())


def _cone(na: float) -> float:
    """Solid angle of the cone of numerical aperture na in air, sr."""
    return 2.0 * math.pi * (1.0 - math.sqrt(1.0 - na * na))


@pytest.mark.slow
@pytest.mark.parametrize("lens", [pytest.param(p, id=p.stem) for p in FINITE_CORPUS])
def test_a_finite_conjugate_corpus_lens_goes_from_init_to_light_on_its_detector(lens, tmp_path):
    """init → regenerate → check (exit 0 or 1, never a traceback; the pupil as the object-space NA) →
    each scene init wrote brings light to the detector: case 2's stray fraction > 0 with its error bar,
    the object's direct image > 0. And the flux of an axial object point through the lens is the étendue
    the mount passes: I·Ω of the cone `check` measured (sequential real rays against the mesh), over
    I·Ω of the designed cone, the normalisation of the source (lossless glass, perfect AR), by both
    estimators."""
    runner, design = CliRunner(), tmp_path / "design"
    made = runner.invoke(app, ["init", str(design), "--lens", str(lens)])
    assert made.exit_code == 0, made.output
    reg = runner.invoke(app, ["regenerate", str(design), "--quiet"])
    assert reg.exit_code == 0, reg.output
    checked = runner.invoke(app, ["check", str(design)])
    assert checked.exit_code in (0, 1) and isinstance(checked.exception, (SystemExit, type(None))), checked.output
    assert "entrance pupil: realised NA" in checked.output, checked.output
    pupil = json.loads((design / "build" / "check" / "check.json").read_text())["entrance_pupil"]
    assert 0.0 < pupil["realised_object_na"] < 1.0 and 0.0 < pupil["design_object_na"] < 1.0

    scenes = sorted((design / "scenes").glob("*.toml"))
    assert [s.stem for s in scenes] == ["case2-lambertian", "object-lambertian"]
    for scene in scenes:
        direct = tomllib.loads(scene.read_text())["effects"]["direct"]
        summary = _simulate(design, scene, tmp_path / scene.stem, 20_000 if direct else 100_000)
        if direct:
            image = summary["per_part"]["direct"]
            assert image["fraction"] > 0.0 and 0.0 < image["std_error"] < 0.2 * image["fraction"], image
            with OpenEXR.File(str(tmp_path / scene.stem / "irradiance.exr")) as exr:   # the images say their unit
                assert exr.header()["lensmount_units"] == "E/E_ref"
        else:
            fraction, error = summary["stray_fraction"], summary["stray_fraction_std_error"]
            print(f"{lens.stem} {scene.stem}: stray fraction {fraction:.3g} +- {error}")
            assert fraction > 0.0 and error is not None and 0.0 < error < fraction, summary["tail"]

    axial = design / "scenes" / "axial-point.toml"
    axial.write_text('[source]\ntype = "point"\n[detector]\nwidth_mm = 10.0\nheight_mm = 10.0\npixels = [100, 100]\n'
                     "[effects]\ndirect = true\nscatter = false\nabsorption = false\n")
    expected = _cone(pupil["realised_object_na"]) / _cone(pupil["design_object_na"])
    for method in ("bidirectional", "forward"):   # the view map's estimate and the photons' own walk
        image = _simulate(design, axial, tmp_path / f"axial-{method}", 50_000, method)["per_part"]["direct"]
        print(f"{lens.stem} axial point, {method}: {image['fraction']:.4f} +- {image['std_error']:.4f}, "
              f"étendue {expected:.4f}")
        assert image["fraction"] == pytest.approx(expected, abs=max(4 * image["std_error"], 0.01))


TELECENTRIC_SINGLET = """VERS 120928 10 30221
MODE SEQ
NAME a singlet with its stop at its rear focus: telecentric object space
UNIT MM X W X CM MR CPMM
OBNA 5.0E-2 0
FTYP 1 1 2 1 0 0 0
YFLN 0 4.0 0 0 0 0 0 0 0 0 0 0
WAVM 1 5.875618E-1 1
PWAV 1
SURF 0
  CURV 0.0 0 0 0 0 ""
  DISZ 200
SURF 1
  CURV 0.0 0 0 0 0 ""
  DISZ 6
  GLAS ___BLANK 1 0 1.5 0 0 0 0 0 0 0
SURF 2
  CURV -0.02 0 0 0 0 ""
  DISZ 100
SURF 3
  STOP
  CURV 0.0 0 0 0 0 ""
  DISZ 96.15384615384615
SURF 4
  CURV 0.0 0 0 0 0 ""
  DISZ 0
"""


def test_an_entrance_pupil_at_infinity_puts_case_2_beyond_the_field_seen_from_the_lens(tmp_path):
    """Telecentric object space (the stop at the rear focus: the entrance pupil ~1e18 mm away) sees every
    object height at 0°: case 2's point then stands 5° beyond the field's edge seen from surface 1's vertex."""
    from lensmount.optics.paraxial import object_height_at

    lens = tmp_path / "telecentric.zmx"
    lens.write_text(TELECENTRIC_SINGLET)
    p = load_lens(lens)
    assert abs(paraxial(p).entrance_pupil_z) > 1e12 and p.object_heights_mm == (0.0, 4.0)
    h = object_height_at(p, p.max_field_deg + 5.0)
    assert math.degrees(math.atan(h / 200.0) - math.atan(4.0 / 200.0)) == pytest.approx(5.0)
