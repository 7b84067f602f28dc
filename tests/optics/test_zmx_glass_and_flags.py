"""OpticStudio's MEMA/DIAM flags and the glass resolution of a .zmx, each against a hand figure."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.lens import load_lens
from lensmount.errors import InputError
from lensmount.optics.glass import refractive_index
from lensmount.optics.io.agf import parse_agf
from lensmount.optics.io.zemax import convert, parse_zmx
from lensmount.optics.paraxial import paraxial

D_LINE = 0.5875618
C1, C2, T = 0.02, -0.0125, 6.0      # the singlet below: R 50 / R -80, 6 mm thick
DOUBLET = ["UNIT MM", "ENPD 10", "FTYP 0 0 1 1 0 0 0", "YFLN 0", "WAVM 1 0.5875618 1",
           "SURF 0", "  DISZ INFINITY",
           "SURF 1", "  STOP", "  CURV 0.02", "  DISZ 6", "  GLAS {glass1}", "{surf1}",
           "SURF 2", "  CURV -0.0125", "  DISZ 90", "  {glass2}", "{surf2}",
           "SURF 3"]


def _zmx(glass1="N-BK7", surf1="", surf2="", glass2=""):
    return "\n".join(DOUBLET).format(glass1=glass1, surf1=surf1, surf2=surf2, glass2=glass2)


def _convert(text, catalogues=()):
    return convert(parse_zmx(text, "t.zmx"), "t.zmx", catalogues)


def _thick_lens_efl(n):
    return 1.0 / ((n - 1) * (C1 - C2 + (n - 1) * T * C1 * C2 / n))


# ------------------------------------------------------------------------------------------ MEMA / DIAM


def test_an_automatic_mema_without_chip_zone_is_left_to_the_mount_and_a_fixed_one_is_kept():
    """OpticStudio 2019+ writes MEMA on every surface; flag 0 is its automatic value, which with no
    chip zone equals the clear semi-diameter: on an automatic DIAM (the beam's) no edge to hold the glass
    by; on a fixed DIAM the beam stays inside (here 5 mm of 8), the edge OpticStudio draws the glass to."""
    auto = "  DIAM 8 0 0 0 1 \"\"\n  MEMA 8 0 0 0 1 \"\""
    lens, notes = _convert(_zmx(surf1=auto, surf2=auto))
    assert [s.mechanical_semi_diameter for s in lens.surfaces] == [None, None]
    assert [s.clear_semi_diameter for s in lens.surfaces] == [8.0, None]   # the stop's automatic DIAM stays
    assert sum("automatic in the file" in n.what and "mechanical" in n.what for n in notes) == 2
    edge = "  DIAM 8 1 0 0 1 \"\"\n  MEMA 8 0 0 0 1 \"\""
    lens, notes = _convert(_zmx(surf1=edge, surf2=edge))
    assert [s.mechanical_semi_diameter for s in lens.surfaces] == [8.0, 8.0]
    assert [s.clear_semi_diameter for s in lens.surfaces] == [None, None]   # the beam's, from real rays
    assert any(n.kind == "substituted" and "the element's glass ends there" in n.what for n in notes)
    fixed = "  DIAM 8 1 0 0 1 \"\"\n  MEMA 9.5 1 0 0 1 \"\""
    lens, notes = _convert(_zmx(surf1=fixed, surf2=fixed))
    assert [s.mechanical_semi_diameter for s in lens.surfaces] == [9.5, 9.5]
    assert any(n.kind == "imported" and "mechanical semi-diameter 9.5 mm, fixed" in n.what for n in notes)


def test_an_automatic_mema_with_a_chip_zone_is_the_elements_largest_clear_semi_diameter_plus_the_zone():
    """Edmund's catalogue files: DIAM 5.75 fixed, OEMA 0.5, MEMA automatic: 6.25 mm, the 12.5 mm part."""
    s1 = "  DIAM 5.75 1 0 0 1 \"\"\n  OEMA 0.5 0 0 0 0 \"\"\n  MEMA 6.25 0 0 0 1 \"\""
    s2 = "  DIAM 5.5 1 0 0 1 \"\"\n  OEMA 0.5 0 0 0 0 \"\"\n  MEMA 6.0 0 0 0 1 \"\""
    lens, _ = _convert(_zmx(surf1=s1, surf2=s2))
    assert [s.mechanical_semi_diameter for s in lens.surfaces] == [5.75 + 0.5, 5.75 + 0.5]


def test_a_mema_picked_up_from_an_automatic_one_is_automatic_and_a_pickup_of_a_fixed_one_is_kept():
    s1 = "  DIAM 8 0 0 0 1 \"\"\n  MEMA 9 {flag} 0 0 1 \"\""
    s2 = "  DIAM 8 0 0 0 1 \"\"\n  MEMA 9 2 1 0 1 \"\""
    lens, _ = _convert(_zmx(surf1=s1.format(flag=0), surf2=s2))
    assert [s.mechanical_semi_diameter for s in lens.surfaces] == [None, None]
    lens, _ = _convert(_zmx(surf1=s1.format(flag=1), surf2=s2))
    assert [s.mechanical_semi_diameter for s in lens.surfaces] == [9.0, 9.0]


def test_an_automatic_mema_beyond_the_spheres_reach_is_no_refusal(tmp_path):
    """An automatic MEMA is OpticStudio's computed value, not a given one: a MEMA larger than a face's
    radius (as in Zemax's own double Gauss) does not refuse the lens."""
    text = _zmx(surf1="  DIAM 8 1 0 0 1 \"\"\n  MEMA 60 0 0 0 1 \"\"", surf2="  MEMA 60 0 0 0 1 \"\"")
    path = tmp_path / "mema.zmx"
    path.write_text(text)
    lens = load_lens(path)
    assert lens.surfaces[0].mechanical_semi_diameter == 8.0   # OpticStudio's automatic MEMA: the fixed DIAM
    with pytest.raises(InputError) as err:                 # the same value given (flag 1) is refused
        path.write_text(text.replace("MEMA 60 0", "MEMA 60 1"))
        load_lens(path)
    assert "mechanical semi-diameter 60" in err.value.paragraph()


# ------------------------------------------------------------------------------------------ glasses


def test_a_model_glass_with_vd_0_is_a_constant_index():
    """GLAS ___BLANK 1 0 1.52825 0 is the model glass n_d 1.52825 with V_d 0 (no dispersion), named
    '1.52825/0', not '1.52825/1e+09'."""
    lens, notes = _convert(_zmx(glass1="___BLANK 1 0 1.52825 0 0 0 0 0 0 0"))
    assert lens.surfaces[0].material == "1.52825/0"
    for wl in (0.4, D_LINE, 1.0):
        assert paraxial(lens, wl).efl == pytest.approx(_thick_lens_efl(1.52825), rel=1e-12)
    assert any("constant index" in n.what for n in notes)


def test_an_unknown_glass_with_placeholders_names_file_line_surface_catalogues_and_near_names():
    with pytest.raises(InputError) as err:
        _convert(_zmx(glass1="N-BK8 0 0 1.5 40 0 0 0 0 0 0"))
    text = err.value.paragraph()
    assert err.value.file == "t.zmx" and err.value.line == 12 and "surface 1" in text
    assert "placeholders" in text and "Schott" in text and "legacy" in text and "N-BK7" in text
    assert "\n" not in text


def test_a_glass_with_data_on_one_surface_and_placeholders_on_another_resolves_the_same_on_both():
    """One catalogue name with different model data on two GLAS lines: D263T with n_d/V_d on one and
    1.5/40 on the other. Schott's D 263 T eco data (refractiveindex.info, CC0): n_d 1.5233, and both surfaces take it."""
    lens, notes = _convert(_zmx(glass1="D263T 0 0 1.5231 55 0 0 0 0 0 0").replace(
        "SURF 2\n  CURV -0.0125\n  DISZ 90", "SURF 2\n  CURV 0\n  DISZ 2\n  GLAS D263T 0 0 1.5 40\n"
        "SURF 4\n  CURV -0.0125\n  DISZ 90").replace("SURF 3", "SURF 5"))
    assert lens.surfaces[0].material == lens.surfaces[1].material
    assert float(lens.surfaces[0].material.split("/")[0]) == pytest.approx(1.5233, abs=2e-4)
    assert any("table of legacy" in n.what and "D263TECO" in n.what for n in notes)


# A user's .agf catalogue of one glass (MYCROWN), shared with the readers' fuzzing as a seed.
AGF = (Path(__file__).parent / "data" / "user-catalogue.agf").read_text()


def _sellmeier_by_hand(wl):
    l2 = wl * wl
    return math.sqrt(1 + 1.1 * l2 / (l2 - 0.006) + 0.2 * l2 / (l2 - 0.02) + 1.0 * l2 / (l2 - 100.0))


def test_an_agf_catalogue_supplies_a_glass_the_built_in_catalogues_lack(tmp_path):
    agf = tmp_path / "MYVENDOR.AGF"
    agf.write_bytes(b"\xff\xfe" + AGF.encode("utf-16-le"))     # UTF-16 with a BOM, as Zemax writes it
    text = _zmx(glass1="MYCROWN 0 0 1.5 40 0 0 0 0 0 0")
    with pytest.raises(InputError):
        _convert(text)                                        # no catalogue has it
    lens, notes = _convert(text, [agf])
    assert lens.surfaces[0].material.startswith("MYVENDOR") and lens.surfaces[0].material.endswith(":MYCROWN")
    n = _sellmeier_by_hand(D_LINE)
    assert paraxial(lens, D_LINE).efl == pytest.approx(_thick_lens_efl(n), rel=1e-12)
    assert any("user catalogue" in n.what and str(agf.resolve()) in n.what for n in notes)
    # the same through lens.toml's glass_catalogs (a path from the lens.toml's folder) and inspect
    (tmp_path / "lens.toml").write_text(
        'aperture = { entrance_pupil_diameter = 10 }\nglass_catalogs = ["MYVENDOR.AGF"]\n'
        '[[surface]]\nradius = 50\nthickness = 6\nmaterial = "MYCROWN"\nstop = true\n'
        '[[surface]]\nradius = -80\nthickness = 90\n')
    lens = load_lens(tmp_path / "lens.toml")
    assert paraxial(lens, D_LINE).efl == pytest.approx(_thick_lens_efl(n), rel=1e-12)
    zmx = tmp_path / "singlet.zmx"
    zmx.write_text(text)
    result = CliRunner().invoke(app, ["inspect", str(zmx), "--glass-catalog", str(agf), "--json"])
    assert result.exit_code == 0, result.output
    assert "user catalogue" in result.stdout


def test_agf_dispersion_formulas_against_their_formulas():
    text = ("NM S1 1 0 1.5 60 0 0 0\nCD 2.27 -0.0101 0.0105 0.00023 -6e-06 4e-07\n"
            "NM H 3 0 1.5 60 0 0 0\nCD 1.5 0.004 0.0001 -0.002 1e-05 -1e-07\n"
            "NM C 5 0 1.5 60 0 0 0\nCD 1.49 0.006 0.0002\n")
    glasses = parse_agf(text)
    wl = 0.55
    schott = math.sqrt(2.27 - 0.0101 * wl**2 + 0.0105 / wl**2 + 0.00023 / wl**4 - 6e-6 / wl**6 + 4e-7 / wl**8)
    big_l = 1 / (wl**2 - 0.028)
    herzberger = 1.5 + 0.004 * big_l + 0.0001 * big_l**2 - 0.002 * wl**2 + 1e-5 * wl**4 - 1e-7 * wl**6
    conrady = 1.49 + 0.006 / wl + 0.0002 / wl**3.5
    assert float(glasses["S1"].index(wl)) == pytest.approx(schott, rel=1e-14)
    assert float(glasses["H"].index(wl)) == pytest.approx(herzberger, rel=1e-14)
    assert float(glasses["C"].index(wl)) == pytest.approx(conrady, rel=1e-14)
    with pytest.raises(InputError) as err:
        parse_agf("NM X 13 0 1.5 60 0 0 0\nCD 1 2 3\n", "x.agf")
    assert err.value.line == 1 and "formula 13" in err.value.paragraph()
    assert np.isfinite(glasses["S1"].index(np.array([0.4, 0.7]))).all()


def test_a_material_offset_adds_to_the_catalogue_glass_n_d_and_v_d():
    """OpticStudio's offset mode: GLAS name 4 ... dn dv (prescription minus catalogue)."""
    lens, notes = _convert(_zmx(glass1="N-BK7 4 0 1.5168 64.17 0 0 0 0 0.001 -0.5"))
    nd, nf, nc = (float(refractive_index("N-BK7", wl)) for wl in (D_LINE, 0.4861327, 0.6562725))
    assert lens.surfaces[0].material == f"{nd + 0.001:.12g}/{(nd - 1) / (nf - nc) - 0.5:.12g}"
    assert paraxial(lens, D_LINE).efl == pytest.approx(_thick_lens_efl(nd + 0.001), rel=1e-10)
    assert any("offsets" in n.what for n in notes)


def test_the_active_configuration_is_said_and_an_ideal_lens_is_refused_for_what_it_is():
    _, notes = _convert("MNUM 3 2\n" + _zmx())
    assert any(n.where == "configurations" and "configuration 2 of 3" in n.what for n in notes)
    with pytest.raises(InputError) as err:
        _convert(_zmx().replace("SURF 1\n  STOP", "SURF 1\n  STOP\n  TYPE PARAXIAL"))
    assert "ideal thin lens" in err.value.paragraph() and err.value.line == 10


def test_an_extended_asphere_is_the_even_asphere_of_its_terms_over_the_normalisation_radius():
    """XASPHERE: term k multiplies (r / r0)^(2k); OpticStudio 2023 writes XDAT 1 N, XDAT 2 r0, XDAT k+2."""
    from lensmount.optics.profiles import Profile

    r0, a4, a6 = 5.0, 2e-2, -3e-3            # on rho^4 and rho^6
    extended = _zmx().replace("  CURV 0.02\n", "  TYPE XASPHERE\n  CURV 0.02\n  XDAT 1 3 0 0 1 0 0 \"\"\n"
                              f"  XDAT 2 {r0} 0 0 1 0 0 \"\"\n  XDAT 3 0\n  XDAT 4 {a4}\n  XDAT 5 {a6}\n")
    lens, _ = _convert(extended)
    r = 4.0
    by_hand = 0.02 * r**2 / (1 + math.sqrt(1 - 0.02**2 * r**2)) + a4 * (r / r0) ** 4 + a6 * (r / r0) ** 6
    assert float(Profile.of(lens.surfaces[0]).sag(np.array([r * r]))[0]) == pytest.approx(by_hand, rel=1e-14)
    with pytest.raises(InputError) as err:
        _convert(extended.replace("  XDAT 3 0\n", "  XDAT 3 1e-3\n"))
    assert "r^2" in err.value.paragraph() and err.value.line == 14


def test_a_catalogue_the_gcat_line_names_is_read_from_beside_the_file(tmp_path):
    """As Zemax finds GCAT's catalogues in its glass folder: MYVENDOR.agf next to the .zmx."""
    from lensmount.optics.io.zemax import read_zmx_with_notes

    (tmp_path / "myvendor.agf").write_text(AGF)
    path = tmp_path / "lens.zmx"
    path.write_text("GCAT SCHOTT MYVENDOR\n" + _zmx(glass1="MYCROWN 0 0 1.5 40 0 0 0 0 0 0"))
    lens, notes = read_zmx_with_notes(path)
    assert paraxial(lens, D_LINE).efl == pytest.approx(_thick_lens_efl(_sellmeier_by_hand(D_LINE)), rel=1e-12)
    assert any(n.where == "glass catalogues" and "myvendor.agf" in n.what for n in notes)


def test_glass_catalog_on_init_supplies_the_glass_for_that_command_only(tmp_path):
    """`--glass-catalog` is one option shared by every command that reads a lens (lensmount.cli.options):
    init reads a singlet whose glass only the .agf written here holds; without the option it is refused,
    with it the design is derived; the next command without the option no longer sees the catalogue."""
    agf = tmp_path / "MYVENDOR.AGF"
    agf.write_text(AGF)
    zmx = tmp_path / "singlet.zmx"
    zmx.write_text(_zmx(glass1="MYCROWN 0 0 1.5 40 0 0 0 0 0 0"))
    refused = CliRunner().invoke(app, ["init", str(tmp_path / "without"), "--lens", str(zmx)])
    assert refused.exit_code == 2 and "MYCROWN" in refused.output
    made = CliRunner().invoke(app, ["init", str(tmp_path / "with"), "--lens", str(zmx), "--glass-catalog", str(agf)])
    assert made.exit_code == 0, made.output
    assert (tmp_path / "with" / "mount.toml").is_file()
    lens = load_lens(tmp_path / "with" / "lens.zmx", glass_catalogs=[agf])
    assert paraxial(lens, D_LINE).efl == pytest.approx(_thick_lens_efl(_sellmeier_by_hand(D_LINE)), rel=1e-12)
    after = CliRunner().invoke(app, ["inspect", str(zmx)])
    assert after.exit_code == 2 and "MYCROWN" in after.output


def test_a_reformulated_glass_is_found_under_its_new_name_and_a_dropped_one_in_the_table():
    """Schott marks a glass melted to a changed formula with an A (N-PK52 -> N-PK52A); a glass its
    current catalogue dropped (N-SK15) is in the table of legacy glasses, with Schott's own data
    (refractiveindex.info, CC0: n_d 1.62296), not another maker's look-alike (Sumita K-SK15, 1.62299)."""
    from lensmount.optics.glass import resolve_glass, successor

    assert successor("N-PK52") == "SCHOTT:N-PK52A"
    found = resolve_glass("N-SK15")
    assert "table of legacy" in found.step and found.material.startswith("1.62296/")
