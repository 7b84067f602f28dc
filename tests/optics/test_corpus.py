"""Public .zmx files (tests/optics/corpus, origins in SOURCES.md) against an independent optics package.

optiland (PyPI, no GUI dependencies) reads each file with its own Zemax reader, its own
glass data (refractiveindex.info) and its own paraxial code; lensmount's effective focal
length must agree within 1e-9 relative with the same indices, 1e-4 with each package's glass data. Both are compared at the d line (587.5618 nm),
where a model glass is exactly the file's n_d whatever dispersion formula each package
fits through it. Where optiland cannot resolve a glass name either (it then falls back to
Zemax's 1.5/40 placeholder), it is given the substitute lensmount chose, from optiland's
own database (a catalogue successor), or the model glass lensmount chose (optiland's
AbbeMaterial of the same n_d and V_d: the table of legacy glasses, the GLAS line's data), so
that the comparison is of the optics, not of the name lookup.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.edges import MAX_CLIP_VIGNETTING
from lensmount.design.lens import load_lens, load_lens_and_clips
from lensmount.errors import InputError
from lensmount.optics.glass import MODEL_GLASS, refractive_index
from lensmount.optics.io.zemax import parse_zmx, read_zmx_with_notes
from lensmount.optics.io.zemax_file import read_text
from lensmount.optics.paraxial import paraxial

CORPUS = Path(__file__).parent / "corpus"
FILES = sorted(p for p in CORPUS.glob("*.zmx"))
OUT_OF_SCOPE = sorted((CORPUS / "out_of_scope").glob("*.zmx"))
REFUSED_FILES = sorted((CORPUS / "refused").glob("*.zmx"))
D_LINE = 0.5875618


def _optiland_efl(path: Path, notes, lens=None) -> float:
    """optiland's EFL of the file: with its own glass data (`lens` None; a name it cannot resolve gets
    lensmount's substitute), or with lensmount's index at the d line on every glass (`lens` given),
    which compares the optics alone (radii, thicknesses, units, pickups) free of glass databases."""
    import optiland.fileio as optiland_fileio  # heavy: imported by the slow test only
    import optiland.materials as optiland_materials

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        optic = optiland_fileio.load_zemax_file(str(path))
        surfaces = optic.surface_group.surfaces
        for note in notes:
            catalogue = re.match(r"glass \S+ -> (\w+):([^\s,]+)", note.what)
            model = re.search(r"-> (?:model glass n_d )?([\d.]+)(?:/|, V_d )([\d.]+)", note.what)
            if lens is not None or note.kind != "substituted" or not (catalogue or model):
                continue
            k = int(note.where.split()[1])
            if not isinstance(surfaces[k].material_post, optiland_materials.AbbeMaterial):
                continue
            optic.set_material(optiland_materials.Material(catalogue.group(2), catalogue.group(1).lower())
                               if catalogue else optiland_materials.AbbeMaterial(float(model.group(1)),
                                                                                 float(model.group(2))), k)
        for k, material in _lensmount_materials(path, lens or read_zmx_with_notes(path)[0]):
            placeholder = isinstance(surfaces[k].material_post, optiland_materials.AbbeMaterial) and (
                float(np.ravel(surfaces[k].material_post.n(D_LINE))[0]) == 1.5)
            if lens is not None or placeholder or MODEL_GLASS.match(material):
                # a name optiland cannot resolve, or a model glass (exactly n_d at the d line, whatever
                # dispersion formula each package fits through it): lensmount's index
                optic.set_material(optiland_materials.IdealMaterial(float(refractive_index(material, D_LINE))), k)
        optic.add_wavelength(D_LINE, is_primary=True)
        return float(np.ravel(optic.paraxial.f2())[0])


def _lensmount_materials(path: Path, lens):
    """(the file's SURF number, lensmount's material) of every surface lensmount keeps that is not in air."""
    notes = read_zmx_with_notes(path)[1]
    merged = {int(n) for note in notes if "the stop is that face" in note.what     # stop planes on a lens face
              for n in re.findall(r"\d+", note.where)}
    numbers = [zs.number for zs in parse_zmx(read_text(path), str(path)).surfaces[1:-1]
               if zs.type != "COORDBRK" and zs.number not in merged]
    assert len(numbers) == len(lens.surfaces)   # no dummy surfaces between breaks in the corpus's focusing lenses
    return [(k, s.material) for k, s in zip(numbers, lens.surfaces) if not s.is_air_after]


def test_the_corpus_holds_the_kinds_of_file_the_issue_names():
    texts = {p.name: p.read_bytes() for p in FILES}
    assert len(FILES) + len(OUT_OF_SCOPE) + len(REFUSED_FILES) >= 35          # at least 35 public files
    sources = (CORPUS / "SOURCES.md").read_text(encoding="utf-8")
    assert len(set(re.findall(r"\| ([\w.-]+/[\w.-]+), ", sources))) >= 6     # from at least six repositories
    assert {"thorlabs", "edmund", "cots"} <= {p.name.split("-")[0] for p in FILES}  # three vendors' catalogues
    assert any(b"___BLANK 1 0 1.333" in t.decode("utf-16").encode() for t in texts.values()
               if t.startswith(b"\xff\xfe"))                                # an image formed in water
    assert any(t.startswith(b"\xff\xfe") for t in texts.values())             # UTF-16 as Zemax writes it
    assert any(b"GLAS MIRROR" in t for t in texts.values())                   # mirrors
    assert any(re.search(rb"DIAM \S+ 2 ", t) for t in texts.values())          # semi-diameter pickups
    assert any(re.search(rb"OBNA", t) for t in texts.values())                 # finite conjugate
    assert (CORPUS / "SOURCES.md").read_text(encoding="utf-8").count(".zmx") >= len(FILES) + len(OUT_OF_SCOPE) + len(
        REFUSED_FILES)


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_corpus_file_imports(path):
    lens, notes = read_zmx_with_notes(path)
    assert np.isfinite(paraxial(lens).efl) and notes
    if path.stem == "US00583336-2-scaled":  # the symmetric Double Gauss picks its rear half up from the front
        rear = {n.where: n.what for n in notes if n.what.startswith("pickups")}
        assert "curvature from surface 6" in rear["SURF 8"] and "thickness from surface 5" in rear["SURF 8"]
        assert lens.surfaces[7].radius == pytest.approx(-lens.surfaces[5].radius, rel=1e-15)
        assert "picked up from surface 5" in next(n.what for n in notes if n.where == "SURF 8" and "glass" in n.what)


@pytest.mark.slow  # optiland's start-up and glass database take ~60 s for the corpus on the shared machine
@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_corpus_file_efl_matches_optiland(path):
    """To 1e-9 with the same indices (the optics); to 1e-4 with each package's own glass data (the
    catalogues' releases differ: legacy SF10 against N-SF10, Schott's 2017 against opticalglass's data)."""
    if "TYPE QED_TYPE" in read_text(path):
        pytest.skip("optiland's reader has no Q-type surface; test_qtype.py checks this EFL independently")
    lens, notes = read_zmx_with_notes(path)
    efl = paraxial(lens, D_LINE).image_space_focal_length   # optiland's f2: n' efl (n' = 1 in air)
    assert np.isfinite(efl)
    assert efl == pytest.approx(_optiland_efl(path, notes, lens), rel=1e-9)
    assert efl == pytest.approx(_optiland_efl(path, notes), rel=1e-4)


def _sphere_sag(curvature: float, h: float) -> float:
    r = 1.0 / curvature
    return r - np.sign(r) * np.sqrt(r * r - h * h)


@pytest.mark.slow
@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_corpus_file_loads_with_real_ray_semi_diameters(path):
    lens = load_lens(path)
    assert all(s.clear_semi_diameter is not None and s.clear_semi_diameter > 0 for s in lens.surfaces)


@pytest.mark.slow
def test_us05831776_element_8_is_edged_where_its_faces_keep_1_3_mm_and_inspect_says_so():
    """248 nm lithography lens: between surfaces 15 and 16 (41.227 mm of silica on the axis) the beam of
    the 48 mm field (telecentric object space, as Zemax aims it) reaches 119.3 mm, Zemax's own automatic
    DIAM, where the faces have crossed (edge < 0 by the spheres' sags). The import edges the element where
    1.3 mm of glass remains (0.3 mm minimum edge after two 0.5 mm chamfers); two air gaps whose
    neighbouring faces cross inside the beam are clipped the same way. The axis loses nothing."""
    path = CORPUS / "US05831776-1.zmx"
    c15, c16 = 1.588451323497642800e-3, -4.410343667209579800e-3   # the file's CURV of surfaces 15 and 16
    assert 41.227 + _sphere_sag(c16, 118.4) - _sphere_sag(c15, 118.4) < 0.0
    lens, clips = load_lens_and_clips(path)
    assert [c.surfaces for c in clips] == [(14, 15), (23, 24), (27, 28)]
    h = lens.surfaces[14].clear_semi_diameter
    assert lens.surfaces[15].clear_semi_diameter == h and clips[0].height == h
    assert 41.227 + _sphere_sag(c16, h) - _sphere_sag(c15, h) == pytest.approx(1.3, abs=1e-6)
    lost = np.sum([c.lost for c in clips], axis=0)
    assert lost[0] == 0.0 and 0.0 < lost.max() < MAX_CLIP_VIGNETTING
    result = CliRunner().invoke(app, ["inspect", str(path), "--json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)["import_notes"]
    clipped = [r for r in rows if r["kind"] == "clipped"]
    assert [r["where"] for r in clipped] == ["SURF 15-16", "SURF 24-25", "SURF 28-29"]
    assert "vignettes the designed pupil by 0.00 % at 0 mm" in clipped[0]["what"]
    assert next(r for r in rows if r["where"] == "SURF 15" and "semi-diameter" in r["what"])["what"].endswith(
        f"clipped to {h:.4g} mm")


# why each refused file cannot be built, in the words its one-paragraph refusal must hold
REFUSED_BECAUSE = {
    "optiland-lens_floa": "miss surface 1",
    "thorlabs-LC1060-A-negative": "forms no real image",
    "thorlabs-ACN127-020-A-negative": "forms no real image",
    "zemax-double-gauss-experimental-paraxial": "ideal thin lens",
    "deeplens-ef35mm_f2.0-floating-stop": "the stop has no semi-diameter",
    "optiland-flat_transmission_grating": "diffraction grating",
    "forms-microscope-objective-20x-virtual-image": "the image the file puts there is virtual",
}


def test_refused_folder_holds_the_files_whose_reasons_are_listed():
    assert sorted(p.stem for p in REFUSED_FILES) == sorted(REFUSED_BECAUSE)


@pytest.mark.parametrize("path", REFUSED_FILES, ids=[p.stem for p in REFUSED_FILES])
def test_refused_file_exits_2_with_one_paragraph_giving_its_reason(path):
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    text = " ".join(result.output.split())                # the CLI wraps the paragraph to the terminal
    assert REFUSED_BECAUSE[path.stem] in text and path.name in text
    with pytest.raises(InputError) as err:
        load_lens(path)
    assert "\n" not in err.value.paragraph()


def test_floating_stop_wider_than_its_lens_is_refused_in_one_paragraph_naming_surface_1():
    """optiland's FLOA fixture (refused/, SOURCES.md) is no real lens: the 8.5 mm stop 10 mm behind an
    R = ±20 mm, 5 mm thick N-BK7 biconvex lens needs a beam that enters higher than the sphere reaches,
    and the two faces meet at h = 9.68 mm anyway (sags 2.5 + 2.5 mm = the 5 mm centre thickness)."""
    n, r1, r2, t, gap, stop = 1.5168, 20.0, -20.0, 5.0, 10.0, 8.5   # N-BK7 at the d line; the file's numbers
    u1 = -(n - 1.0) / (n * r1)                # paraxial slope in glass per unit entrance height
    y2 = 1.0 + t * u1
    u2 = n * u1 - y2 * (1.0 - n) / r2         # slope in air after surface 2
    assert stop / (y2 + gap * u2) > abs(r1)   # the entrance height that fills the stop
    assert np.sqrt(r1**2 - (abs(r1) - t / 2) ** 2) == pytest.approx(9.68, abs=0.01)   # where the faces meet
    path = CORPUS / "refused" / "optiland-lens_floa.zmx"
    with pytest.raises(InputError) as err:
        load_lens(path)
    assert "\n" not in err.value.paragraph() and "miss surface 1" in err.value.paragraph()
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "surface 1" in result.output and "radius" in result.output


@pytest.mark.parametrize("path", OUT_OF_SCOPE, ids=[p.stem for p in OUT_OF_SCOPE])
def test_out_of_scope_file_gives_one_paragraph_naming_the_surface(path):
    with pytest.raises(InputError) as err:
        read_zmx_with_notes(path)
    text = err.value.paragraph()
    assert "\n" not in text and re.search(r"surface \d+", text) and "rotationally symmetric" in text
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert re.search(r"surface \d+", result.output) and "rotationally symmetric" in result.output


MUTATIONS = {   # each pushes surfaces out of their domain: the beam beyond a sphere, a hyperbola's reach
    "semi-diameters x3": (r"(DIAM )([-\d.Ee+]+)", 3.0),
    "pupil x5": (r"(ENPD )([-\d.Ee+]+)", 5.0),
    "curvatures x3": (r"(CURV )([-\d.Ee+]+)", 3.0),
    "conics x-30": (r"(CONI )([-\d.Ee+]+)", -30.0),
}


@pytest.mark.slow   # 128 imports
@pytest.mark.parametrize("mutation", MUTATIONS)
def test_no_corpus_file_pushed_out_of_its_domain_gives_a_traceback(mutation, tmp_path):
    pattern, factor = MUTATIONS[mutation]
    for path in FILES:
        text = re.sub(pattern, lambda m: m.group(1) + repr(float(m.group(2)) * factor), read_text(path))
        mutated = tmp_path / path.name
        mutated.write_text(text, encoding="utf-8")
        result = CliRunner().invoke(app, ["inspect", str(mutated)])
        assert result.exit_code in (0, 2) and not isinstance(result.exception, Exception), (path.name, result.output)
        if result.exit_code == 2:
            assert "Traceback" not in result.output and mutated.name in result.output
