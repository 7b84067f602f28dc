"""The .zmx reader on the lines real lens files hold, each against an independent figure."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.errors import InputError
from lensmount.optics.placement import require_coaxial
from lensmount.optics.glass import refractive_index
from lensmount.optics.io.zemax import convert, parse_zmx
from lensmount.optics.paraxial import paraxial
from lensmount.optics.realrays import chief_ray, marginal_ray

SINGLET = ["UNIT MM", "{aperture}", "FTYP {ftyp} 0 2 1 0 0 0", "YFLN 0 {field}", "WAVM 1 0.5875618 1",
           "SURF 0", "  DISZ {object}",
           "SURF 1", "  STOP", "  CURV 0.02", "  DISZ 6", "  GLAS {glass}",
           "SURF 2", "  CURV -0.0125", "  DISZ 90",
           "SURF 3"]


def _lens(aperture="ENPD 10", ftyp=0, field=5, obj="INFINITY", glass="N-BK7", extra=()):
    text = "\n".join(SINGLET).format(aperture=aperture, ftyp=ftyp, field=field, object=obj, glass=glass)
    return convert(parse_zmx(text + "\n" + "\n".join(extra), "t.zmx"), "t.zmx")


def _thick_lens_efl(n):
    c1, c2, t = 0.02, -0.0125, 6.0
    power = (n - 1) * (c1 - c2 + (n - 1) * t * c1 * c2 / n)
    return 1.0 / power


def test_legacy_and_unknown_glass_names_are_substituted_and_said_so():
    lens, notes = _lens(glass="BK7 0 0 1.5168 64.17")
    assert lens.surfaces[0].material == "SCHOTT:N-BK7"
    assert any(n.kind == "substituted" and "BK7" in n.what and "N-BK7" in n.what for n in notes)
    lens, notes = _lens(glass="MYGLASS-42 0 0 1.6 40")
    assert lens.surfaces[0].material == "1.6/40"
    assert any(n.kind == "substituted" and "MYGLASS-42" in n.what for n in notes)
    assert paraxial(lens, 0.5875618).efl == pytest.approx(_thick_lens_efl(1.6), rel=1e-12)
    with pytest.raises(InputError) as err:
        _lens(glass="MYGLASS-42 0 0 1.5 40")        # Zemax's placeholder is no data
    assert err.value.line == 12


def test_paraxial_and_real_image_height_fields_land_where_the_file_says():
    n = float(refractive_index("N-BK7", 0.5875618))
    lens, _ = _lens(ftyp=2, field=8)
    # paraxial image height h' = f tan(theta), f by the thick-lens formula
    assert math.tan(math.radians(lens.field_angles_deg[1])) * _thick_lens_efl(n) == pytest.approx(8.0, rel=1e-9)
    lens, _ = _lens(ftyp=3, field=8)
    chief = chief_ray(lens, [lens.field_angles_deg[1]], clip=False)
    assert math.hypot(*chief.image_points[0, :2]) == pytest.approx(8.0, abs=1e-7)


def test_finite_object_with_object_height_and_na_and_working_f_number():
    n = float(refractive_index("N-BK7", 0.5875618))
    lens, _ = _lens(aperture="OBNA 0.05 0", ftyp=1, field=3, obj=200)
    assert lens.object_distance == 200.0 and lens.object_heights_mm == (0.0, 3.0)
    assert lens.aperture.kind == "object_na"
    # the real marginal ray leaves the axial object point at sin u = 0.05 (to the singlet's small aberration)
    rim = marginal_ray(lens, 0.0, clip=False)
    assert rim.start_directions[0, 1] == pytest.approx(0.05, rel=2e-2)
    assert np.allclose(rim.origins[0, :2] - rim.start_directions[0, :2] / rim.start_directions[0, 2] * 200, 0.0,
                       atol=1e-9)                                       # it comes from the object point
    # the field's chief ray leaves the object point at height 3 (aimed to the stop centre)
    chief = chief_ray(lens, [3.0], clip=False)
    start = chief.origins[0] - chief.start_directions[0] / chief.start_directions[0, 2] * 200
    assert math.hypot(start[0], start[1]) == pytest.approx(3.0, rel=1e-9)
    # paraxial working F/# 1/(2 n'u') for a finite object: trace the marginal ray by hand through the thick lens
    lens, _ = _lens(aperture="FNUM 5 1", obj=200)
    epd = lens.aperture.value
    par = paraxial(lens)
    y, u = epd / 2 * 200 / (200 + par.entrance_pupil_z), epd / 2 / (200 + par.entrance_pupil_z)
    u1 = (u - y * (n - 1) * 0.02) / n
    y2 = y + 6 * u1
    u2 = n * u1 - y2 * (1 - n) * -0.0125
    assert 1.0 / (2 * abs(u2)) == pytest.approx(5.0, rel=1e-9)


def test_a_finite_objects_field_angle_is_the_chief_rays_angle_at_the_entrance_pupil():
    """FTYP 0 with an object at a finite distance: OpticStudio measures the angle from the paraxial
    entrance pupil's centre, so the object point is (d + z_EP) tan(theta) high. Here the stop is surface 1
    (z_EP = 0): 200 tan 5° by hand; and Thorlabs MAP105050-A's 4° is its SURF 0 DIAM, 3.629181535504 mm,
    as OpticStudio wrote it (it was read as a 4 mm height)."""
    from pathlib import Path

    from lensmount.design.lens import load_lens

    lens, _ = _lens(ftyp=0, field=5, obj=200)
    assert lens.object_heights_mm[1] == pytest.approx(200.0 * math.tan(math.radians(5.0)), rel=1e-12)
    chief = chief_ray(lens, [lens.object_heights_mm[1]], clip=False)
    d = chief.start_directions[0]
    assert math.degrees(math.atan(math.hypot(d[0], d[1]) / d[2])) == pytest.approx(5.0, abs=1e-9)
    p = load_lens(Path(__file__).parent / "corpus" / "thorlabs-MAP105050-A.zmx")
    assert p.object_heights_mm[1] == pytest.approx(3.629181535504, abs=1e-9)


def test_coordinate_breaks_that_undo_each_other_import_on_one_axis_and_one_that_tilts_a_lens_gives_frames():
    undone = ["SURF 1", "  TYPE COORDBRK", "  PARM 3 5", "  DISZ 0", "SURF 2", "  DISZ 0",
              "SURF 3", "  TYPE COORDBRK", "  PARM 3 -5", "  DISZ 2"]
    text = "\n".join(SINGLET).format(aperture="ENPD 10", ftyp=0, field=5, object="INFINITY", glass="N-BK7")
    text = text.replace("SURF 1\n  STOP", "\n".join(undone) + "\nSURF 4\n  STOP")
    lens, notes = convert(parse_zmx(text, "t.zmx"), "t.zmx")
    assert len(lens.surfaces) == 2 and lens.surfaces[0].radius == pytest.approx(50.0)
    assert sum(1 for n in notes if n.what.startswith("coordinate break")) == 2
    assert lens.surfaces[0].thickness == 6.0 and lens.vertex_z == (0.0, 6.0)   # the 2 mm gap sits before surface 1
    assert lens.frames == ()
    tilted = text.replace("  PARM 3 -5\n  DISZ 2", "  PARM 3 5\n  DISZ 0")
    lens, _ = convert(parse_zmx(tilted, "t.zmx"), "t.zmx")   # the singlet on an axis turned 10° about x
    assert [f.tilts_deg()[0] for f in lens.frames] == pytest.approx([10.0] * 4, abs=1e-12)   # dummy, 2 faces, image
    with pytest.raises(InputError) as err:   # the mount, scene and tracer need one axis: refused where they start
        require_coaxial(lens, "the mount")
    assert "one axis" in err.value.paragraph() and "\n" not in err.value.paragraph()


def test_inspect_prints_the_import_table(tmp_path):
    text = "\n".join(SINGLET).format(aperture="ENPD 10", ftyp=0, field=5, object="INFINITY",
                                     glass="BK7 0 0 1.5168 64.17")
    p = tmp_path / "legacy.zmx"
    p.write_bytes(b"\xff\xfe" + text.encode("utf-16-le"))
    result = CliRunner().invoke(app, ["inspect", str(p)])
    assert result.exit_code == 0, result.output
    assert "substituted" in result.stdout and "N-BK7" in result.stdout and "what the import did" in result.stdout


def test_odd_asphere_with_even_terms_only_is_the_same_sag_and_an_odd_term_is_refused():
    from lensmount.optics.profiles import Profile

    lines = ["ENPD 10", "SURF 0", "  DISZ INFINITY", "SURF 1", "  STOP", "  TYPE ODDASPH", "  CURV 0.02",
             "  PARM 1 0", "  PARM 2 0", "  PARM 3 0", "  PARM 4 1e-5", "  PARM 5 0", "  PARM 6 -2e-8",
             "  DISZ 6", "  GLAS N-BK7", "SURF 2", "  CURV -0.0125", "  DISZ 90", "SURF 3"]
    lens, _ = convert(parse_zmx("\n".join(lines), "o.zmx"), "o.zmx")
    r = 4.0
    by_hand = 0.02 * r**2 / (1 + math.sqrt(1 - 0.02**2 * r**2)) + 1e-5 * r**4 - 2e-8 * r**6
    assert float(Profile.of(lens.surfaces[0]).sag(np.array([r * r]))[0]) == pytest.approx(by_hand, rel=1e-14)
    lines[9] = "  PARM 3 1e-6"
    with pytest.raises(InputError) as err:
        convert(parse_zmx("\n".join(lines), "o.zmx"), "o.zmx")
    assert err.value.line == 10 and "r^3" in err.value.paragraph()


def test_a_vendor_coating_name_is_ignored_and_said_so():
    # Thorlabs files name coatings of their own COATINGTHOR.DAT, which the .zmx does not carry
    text = "\n".join(SINGLET).format(aperture="ENPD 10", ftyp=0, field=5, object="INFINITY", glass="N-BK7")
    lens, notes = convert(parse_zmx(text.replace("  STOP\n", "  STOP\n  COAT THORA\n"), "t.zmx"), "t.zmx")
    assert lens.surfaces[0].coating is None
    assert any(n.kind == "ignored" and n.where == "SURF 1" and "THORA" in n.what for n in notes)
