"""What a .zmx says about apertures: automatic semi-diameters (DIAM flag 0) are recomputed from
lensmount's own real rays, the designer's vignetting factors shape that beam, and a telecentric
object space aims the rays as Zemax does. The references are the numbers Zemax itself wrote into
the public corpus files (tests/optics/corpus, SOURCES.md), not lensmount's.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from lensmount.optics.apertures import vignetted_pupils, with_clear_semi_diameters
from lensmount.optics.io.zemax import parse_zmx, read_zmx, read_zmx_with_notes
from lensmount.optics.io.zemax_file import read_text
from lensmount.optics.realrays import aim, trace

CORPUS = Path(__file__).parent / "corpus"
US00583336 = CORPUS / "US00583336-2-scaled.zmx"
US05831776 = CORPUS / "US05831776-1.zmx"


def _zemax_semi_diameters(path: Path) -> list[float]:
    """The DIAM values of SURF 1..N-1 as the file holds them."""
    values = [float(m) for m in re.findall(r"^\s*DIAM (\S+)", read_text(path), flags=re.M)]
    return values[1:-1]


def test_the_designers_vignetting_factors_bring_the_marginal_rays_onto_the_fixed_apertures():
    """US 583,336 (double Gauss) fixes its element apertures (DIAM ... 1) and vignettes its 17° and 24°
    fields with VDY/VCX/VCY that Zemax set so that the marginal rays just pass them. Aimed at the
    file's own stop (4.215 mm, Zemax's real-ray aiming), the factors as read put the ±y marginal rays
    exactly on the rims: a wrong sign (mirrored) or no factors throws them 0.4-2 mm outside."""
    p = read_zmx(US00583336)
    assert [v[1] for v in p.vignetting] == pytest.approx([0.0, 0.06208442661354, 0.05473246586901])
    clear = np.array([s.clear_semi_diameter or np.inf for s in p.surfaces])
    marginal = np.array([[0.0, 1.0], [0.0, -1.0]])

    def overshoot(q):
        out = []
        for f in q.field_values[1:]:
            o, d = aim(q, [f], vignetted_pupils(q, [f], marginal), stop_radius=4.215000499256)
            out.append((trace(q, o, d, clip=False).heights()[:-1] - clear[:, None]).max())
        return np.array(out)

    assert np.abs(overshoot(p)).max() < 2e-3
    mirrored = replace(p, vignetting=tuple((a, -b, c, d, -e) for a, b, c, d, e in p.vignetting))
    assert overshoot(mirrored).min() > 0.4
    assert overshoot(replace(p, vignetting=())).min() > 0.4


def test_automatic_semi_diameters_are_recomputed_and_a_pickup_of_one_follows(tmp_path):
    p, notes = read_zmx_with_notes(US00583336)
    # SURF 1 (a dummy plane) carries Zemax's automatic value: recomputed; the stop (SURF 7) keeps its
    # automatic 4.215 mm, the diaphragm Zemax sized for F/4.5 with real-ray aiming
    assert p.surfaces[0].clear_semi_diameter is None and p.surfaces[6].clear_semi_diameter == 4.215000499256
    assert {n.where for n in notes if "recomputed from real rays" in n.what} == {"SURF 1"}
    # fixed (flag 1) and pickups of fixed ones (DIAM 4.5 2 6) are the designer's apertures
    assert p.surfaces[5].clear_semi_diameter == p.surfaces[7].clear_semi_diameter == 4.5
    text = read_text(US00583336).replace("  DIAM 4.5 1 0 0 1", "  DIAM 4.5 0 0 0 1")  # SURF 6 automatic
    lens = parse_zmx(text)
    from lensmount.optics.io.zemax import convert

    q, _ = convert(lens)
    assert q.surfaces[5].clear_semi_diameter is None and q.surfaces[7].clear_semi_diameter is None


def test_a_telecentric_lithography_lens_gets_zemaxs_own_automatic_semi_diameters():
    """US 5,831,776 (FTYP 3 1: telecentric object space, OBNA 0.15, object 110.9 mm in front) leaves every
    DIAM to Zemax. Aimed as Zemax aims such a lens (chief rays parallel to the axis, the pupil in direction
    cosines of the NA), lensmount's real rays reach the heights Zemax wrote on every surface, the stop's
    116.9 mm included. (Aimed through the stop's centre instead, surface 1 would need 53.9 mm, not 64.4.)
    lensmount also samples fields between the listed ones, which may only add a little."""
    raw = read_zmx(US05831776)
    assert raw.object_telecentric and all(s.clear_semi_diameter is None for s in raw.surfaces if not s.is_stop)
    raw = raw.with_surfaces([replace(s, clear_semi_diameter=None) for s in raw.surfaces])
    got = np.array([s.clear_semi_diameter for s in with_clear_semi_diameters(raw).surfaces])
    zemax = np.array(_zemax_semi_diameters(US05831776))
    assert np.all(got > zemax - 0.005)
    assert np.all(got < zemax * 1.003 + 0.005)
    assert got[19] == pytest.approx(116.924, abs=0.01)          # the stop: the beam's, not the paraxial 67.8


def test_save_toml_of_a_vignetted_lens_writes_the_semi_diameters_its_factors_give(tmp_path):
    """lens.toml has no vignetting factors: converted, the lens keeps the vignetted beam's apertures."""
    from typer.testing import CliRunner

    from lensmount.cli import app
    from lensmount.design.lens import load_lens

    out = tmp_path / "lens.toml"
    result = CliRunner().invoke(app, ["inspect", str(US00583336), "--save-toml", str(out)])
    assert result.exit_code == 0, result.output
    direct, converted = load_lens(US00583336), load_lens(out)
    assert [s.clear_semi_diameter for s in converted.surfaces] == pytest.approx(
        [s.clear_semi_diameter for s in direct.surfaces], rel=1e-12)
    assert "clear_semi_diameter" in out.read_text()


def test_a_circular_aperture_on_the_stop_smaller_than_the_pupil_sets_the_working_pupil(tmp_path):
    """Edmund #47-728 (optiland's lens2.zmx): ENPD 15 mm, its stop on the front face with a 6.75 mm
    circular aperture (CLAP). OpticStudio keeps 15 mm for its paraxial data and lets the aperture clip
    the real rays; a front stop is its own entrance pupil, so the light that passes is a 13.5 mm pupil,
    which inspect says and the lens carries (the mount's diaphragm and the realised pupil follow it)."""
    p, notes = read_zmx_with_notes(CORPUS / "optiland-lens2.zmx")
    assert p.stop_index == 0 and p.aperture.kind == "epd"
    assert p.aperture.value == pytest.approx(2 * 6.75, rel=1e-12)
    said = [n.what for n in notes if n.where == "aperture" and n.kind == "substituted"]
    assert len(said) == 1 and "circular aperture 6.75 mm" in said[0] and "13.5 mm" in said[0]
    # the file without its aperture keeps its 15 mm
    bare = tmp_path / "lens2-no-clap.zmx"
    bare.write_text(re.sub(r"^\s*CLAP .*$", "", read_text(CORPUS / "optiland-lens2.zmx"), flags=re.M))
    assert read_zmx(bare).aperture.value == pytest.approx(15.0)


# Catalogue diameters, mm, from the part numbers (Thorlabs: AC254 = Ø25.4, AL1815 = Ø18, ACL3026 = Ø30, MAP10
# pairs and 1" singlets Ø25.4; Edmund #55-278: Ø25), independent of the files' DIAM lines
CATALOGUE_DIAMETER_MM = {
    "thorlabs-AC050-008-A": 5.0, "thorlabs-AC127-025-A": 12.7, "thorlabs-AC254-035-A": 25.4,
    "thorlabs-AC254-050-B": 25.4, "thorlabs-AC254-100-A": 25.4, "thorlabs-AC508-080-A": 50.8,
    "thorlabs-AC508-1000-A": 50.8, "thorlabs-ACL2520-A": 25.0, "thorlabs-ACL25416U-A": 25.4,
    "thorlabs-ACL3026U-utf16": 30.0, "thorlabs-AL1210-A-latin1": 12.5, "thorlabs-AL1815-C-latin1": 18.0,
    "thorlabs-AL2520-A": 25.0, "thorlabs-AL50100-A-latin1": 50.0, "thorlabs-ASL10142-A": 25.4,
    "thorlabs-LA1050-A": 50.8, "thorlabs-LA1131-A": 25.4, "thorlabs-LB1761-A": 25.4, "thorlabs-LBF254-050-A": 25.4,
    "thorlabs-LE1234-A": 25.4, "thorlabs-MAP105050-A": 25.4, "edmund-55278-utf16": 25.0,
}


def _catalogue_lens_keeps_its_diameter(name: str):
    from lensmount.design.lens import load_lens

    p = load_lens(CORPUS / f"{name}.zmx")
    for g in p.lens_groups():
        for i in g:
            s = p.surfaces[i]
            assert s.mechanical_semi_diameter == pytest.approx(CATALOGUE_DIAMETER_MM[name] / 2, abs=1e-9), (name, i)
            assert s.clear_semi_diameter < s.mechanical_semi_diameter   # what the beam needs, inside the glass
    return p


def test_a_fixed_diam_with_no_larger_mema_is_the_catalogue_parts_edge_and_init_keeps_it():
    """Thorlabs writes a fixed DIAM of 12.7 mm on every face of MAP105050-A (two Ø1" achromats) and no MEMA:
    OpticStudio draws the glass to it. The beam needs 9.8-10.6 mm there, so the element's glass ends at
    12.7 mm and its clear apertures are the beam's; init's mount takes that rim (it was built 13.4 mm: the
    DIAM read as the clear aperture plus the edge allowance, a part that does not fit a Ø25.4 mm bore)."""
    from lensmount.cad.layout import plan
    from lensmount.cad.starter import _mount
    from lensmount.design.mount import MountSpec

    p = _catalogue_lens_keeps_its_diameter("thorlabs-MAP105050-A")
    mount = _mount(p, "MAP105050-A", True)
    assert "semi_diameter_mm" not in mount["lens_edge"]
    layout = plan(p, MountSpec.model_validate(mount))
    assert [round(x.template.outer_radius, 9) for x in layout.parts if x.kind == "lens"] == [12.7] * 4


@pytest.mark.slow   # real-ray apertures of 21 files
@pytest.mark.parametrize("name", sorted(CATALOGUE_DIAMETER_MM))
def test_every_vendor_singlet_and_doublet_keeps_its_catalogue_diameter(name):
    _catalogue_lens_keeps_its_diameter(name)


def test_a_fixed_diam_the_beam_overfills_stays_an_aperture():
    """US 8,427,765 (a patent's camera lens) fixes its semi-diameters below what its full field and aperture
    need (7.6 mm on surface 1, where the beam reaches 10.3 mm): the design vignettes with them, so they stay
    the clear semi-diameters and the glass extends past them by the mount's edge allowance."""
    p, notes = read_zmx_with_notes(CORPUS / "US08427765-1.zmx")
    assert p.surfaces[0].clear_semi_diameter == pytest.approx(7.6) and p.surfaces[0].mechanical_semi_diameter is None
    assert any(n.where == "SURF 1-2" and "overfills" in n.what for n in notes)
