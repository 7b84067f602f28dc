"""Public .zmx files (tests/optics/corpus, origins in SOURCES.md) against an independent optics package.

optiland (PyPI, no GUI dependencies) reads each file with its own Zemax reader, its own
glass data (refractiveindex.info) and its own paraxial code; lensmount's effective focal
length must agree within 1e-4 relative. Both are compared at the d line (587.5618 nm),
where a model glass is exactly the file's n_d whatever dispersion formula each package
fits through it. Where optiland cannot resolve a glass name either (it then falls back to
Zemax's 1.5/40 placeholder), it is given the substitute lensmount chose, from optiland's
own database, so that the comparison is of the optics, not of the name lookup.
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
from lensmount.optics.io.zemax import read_zmx_with_notes
from lensmount.optics.paraxial import paraxial

CORPUS = Path(__file__).parent / "corpus"
FILES = sorted(p for p in CORPUS.glob("*.zmx"))
OUT_OF_SCOPE = sorted((CORPUS / "out_of_scope").glob("*.zmx"))
REFUSED_FILES = sorted((CORPUS / "refused").glob("*.zmx"))
D_LINE = 0.5875618


def _optiland_efl(path: Path, notes) -> float:
    import optiland.fileio as optiland_fileio  # heavy: imported by the slow test only
    import optiland.materials as optiland_materials

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        optic = optiland_fileio.load_zemax_file(str(path))
        for note in notes:
            m = re.match(r"glass .* -> (\w+):([^\s,]+)", note.what)
            if note.kind != "substituted" or not m:
                continue
            k = int(note.where.split()[1])
            if isinstance(optic.surface_group.surfaces[k].material_post, optiland_materials.AbbeMaterial):
                optic.set_material(optiland_materials.Material(m.group(2), m.group(1).lower()), k)
        optic.add_wavelength(D_LINE, is_primary=True)
        return float(np.ravel(optic.paraxial.f2())[0])


def test_the_corpus_holds_the_kinds_of_file_the_issue_names():
    texts = {p.name: p.read_bytes() for p in FILES}
    assert len(FILES) >= 15                                                   # issue 16: at least 15 public files
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


@pytest.mark.slow  # optiland's start-up and glass database take ~40 s for the corpus on the shared machine
@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_corpus_file_efl_matches_optiland(path):
    lens, notes = read_zmx_with_notes(path)
    efl = paraxial(lens, D_LINE).efl
    reference = _optiland_efl(path, notes)
    assert np.isfinite(efl)
    assert efl == pytest.approx(reference, rel=1e-4)


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
    assert next(r for r in rows if r["where"] == "SURF 15")["what"].endswith(f"clipped to {h:.4g} mm")


def test_refused_folder_holds_the_floating_stop_fixture():
    assert [p.name for p in REFUSED_FILES] == ["optiland-lens_floa.zmx"]


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
