"""lens.toml and Zemax .zmx readers, the lens.toml writer, and the loader's checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lensmount.cli.inspect import inspect_document
from lensmount.design.lens import load_lens, save_lens_toml
from lensmount.errors import InputError
from lensmount.optics.glass import refractive_index
from lensmount.optics.io.lens_toml import parse_lens_toml
from lensmount.optics.io.zemax import parse_zmx, to_prescription
from lensmount.optics.paraxial import paraxial

MINI = """
name = "singlet"
aperture = { entrance_pupil_diameter = 10.0 }

[[surface]]
radius = 50.0
thickness = 6.0
material = "N-BK7"
stop = true

[[surface]]
radius = -80.0
thickness = 90.0
"""


def _zmx_lines(path):
    return path.read_text(encoding="utf-8").splitlines()


def test_zmx_and_toml_twins_give_identical_inspect_numbers(examples):
    a = inspect_document(load_lens(examples["cooke_toml"]))
    b = inspect_document(load_lens(examples["cooke_zmx"]))
    for d in (a, b):  # the .zmx's DIAMs are Zemax's automatic ones: recomputed like the toml's, but
        d["surfaces"][3].pop("clear_semi_diameter_mm")   # the stop's stays (the diaphragm's 3.8 mm)
    assert a == b
    assert a["efl_mm"] == pytest.approx(50.0, rel=0.01)     # the Cooke sample is a 50 mm lens


def test_utf16_zmx_reads_like_utf8(examples, tmp_path):
    text = examples["cooke_zmx"].read_text(encoding="utf-8")
    for enc in ("utf-16", "utf-16-le"):
        p = tmp_path / f"cooke-{enc}.zmx"
        p.write_bytes(text.encode(enc))
        assert load_lens(p) == load_lens(examples["cooke_zmx"])


def test_unsupported_surface_type_names_the_line(examples, tmp_path):
    lines = _zmx_lines(examples["cooke_zmx"])
    surf3 = lines.index("SURF 3")
    k = next(i for i in range(surf3, len(lines)) if lines[i].strip().startswith("TYPE"))
    lines[k] = "  TYPE TOROIDAL"
    p = tmp_path / "toroid.zmx"
    p.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_lens(p)
    assert err.value.line == k + 1
    assert "TOROIDAL" in err.value.paragraph() and "STANDARD" in err.value.valid


def test_even_asphere_parameters_and_units_are_converted():
    text = "\n".join([
        "UNIT IN X W X CM MR CPMM", "FNUM 4 0", "WAVL 0.55", "YFLD 0 3", "XFLD 0 4",
        "SURF 0", "  DISZ INFINITY",
        "SURF 1", "  STOP", "  TYPE EVENASPH", "  CURV 0.5", "  CONI -0.5", "  PARM 1 0", "  PARM 2 0.01",
        "  PARM 3 -0.002", "  DISZ 0.2", "  GLAS ___BLANK 1 0 1.5168 64.17 0 0 0 0 0 0",
        "SURF 2", "  CURV -0.1", "  DISZ 3.5", "  DIAM 0.8 1 0 0 1 \"\"",
        "SURF 3", "  CURV 0"])
    lens = to_prescription(parse_zmx(text, "a.zmx"), "a.zmx")
    s1, s2 = lens.surfaces
    assert s1.radius == pytest.approx(2.0 * 25.4)
    assert s1.conic == -0.5
    # r^4 and r^6 coefficients in 1/in^3 and 1/in^5 become 1/mm^3 and 1/mm^5
    assert s1.aspheric == pytest.approx((0.01 / 25.4**3, -0.002 / 25.4**5))
    assert s1.thickness == pytest.approx(0.2 * 25.4) and s2.thickness == pytest.approx(3.5 * 25.4)
    assert s1.material == "1.5168/64.17"
    assert s1.clear_semi_diameter is None                 # no DIAM: automatic
    # DIAM ... 1: fixed, no MEMA and the beam inside it: the glass's edge, the clear aperture the beam's
    assert s2.mechanical_semi_diameter == pytest.approx(0.8 * 25.4) and s2.clear_semi_diameter is None
    assert lens.aperture.kind == "fno" and lens.aperture.value == 4.0
    assert lens.wavelengths_um == (0.55,)
    # field (x = 4 deg, y = 3 deg) is the radial angle atan(hypot(tan 4, tan 3))
    expected = math.degrees(math.atan(math.hypot(math.tan(math.radians(4)), math.tan(math.radians(3)))))
    assert lens.field_angles_deg == pytest.approx((0.0, expected))
    # the sag in mm equals the sag in inches times 25.4
    from lensmount.optics.profiles import Profile
    r_in = 0.3
    sag_in = 0.5 * r_in**2 / (1 + math.sqrt(1 - 0.5 * 0.25 * r_in**2)) + 0.01 * r_in**4 - 0.002 * r_in**6
    assert float(Profile.of(s1).sag(np.array([(r_in * 25.4) ** 2]))[0]) == pytest.approx(sag_in * 25.4, rel=1e-12)


def test_r2_asphere_term_is_rejected_and_a_finite_object_images_where_real_rays_focus():
    base = ["ENPD 10", "SURF 0", "  DISZ INFINITY", "SURF 1", "  STOP", "  TYPE EVENASPH", "  CURV 0.01",
            "  PARM 1 0.001", "  DISZ 5", "  GLAS N-BK7", "SURF 2", "  DISZ 50", "SURF 3"]
    with pytest.raises(InputError) as err:
        to_prescription(parse_zmx("\n".join(base), "a.zmx"), "a.zmx")
    assert err.value.line == 8
    finite = list(base)
    finite[2] = "  DISZ 1000"
    finite[7] = "  PARM 1 0"
    lens = to_prescription(parse_zmx("\n".join(finite), "b.zmx"), "b.zmx")
    assert lens.object_distance == 1000.0 and lens.finite_object
    # paraxial image of the object point vs where near-axis real rays from it cross the axis
    from lensmount.optics.realrays import trace
    par = paraxial(lens)
    u = 1e-5
    r = trace(lens, [[0.0, 1000.0 * u, 0.0]], [[0.0, u, 1.0]], clip=False)
    p, d = r.points[-2][0], r.directions[-2][0]
    crossing = p[2] - p[1] / d[1] * d[2]
    assert par.image_z == pytest.approx(crossing, rel=1e-6)


def test_toml_roundtrip_through_the_writer(examples, tmp_path):
    raw = load_lens(examples["double_gauss"], auto_clear_apertures=False)
    out = save_lens_toml(raw, tmp_path / "dg.toml", header="round trip")
    again = load_lens(out, auto_clear_apertures=False)
    assert again == raw
    assert not list(tmp_path.glob(".*.tmp"))               # the temp file was renamed


def test_imported_zmx_saved_as_toml_reads_back_identically(examples, tmp_path):
    raw = load_lens(examples["cooke_zmx"], auto_clear_apertures=False)
    out = save_lens_toml(raw, tmp_path / "lens.toml")
    assert inspect_document(load_lens(out)) == inspect_document(load_lens(examples["cooke_zmx"]))


def test_glass_names_with_catalogue_prefix_and_model_glasses():
    assert float(refractive_index("SCHOTT:N-BK7", 0.5875618)) == pytest.approx(1.5168, abs=1e-4)
    assert float(refractive_index("N-BK7", 0.5875618)) == float(refractive_index("schott:N-BK7", 0.5875618))
    # model glass: n_d exact and n_F - n_C = (n_d - 1) / V_d
    n = refractive_index("1.6/40", np.array([0.5875618, 0.4861327, 0.6562725]))
    assert n[0] == pytest.approx(1.6, abs=1e-14)
    assert n[1] - n[2] == pytest.approx(0.6 / 40, rel=1e-12)
    assert np.all(refractive_index("AIR", np.array([0.4, 0.7])) == 1.0)
    with pytest.raises(InputError):
        refractive_index("NOTAGLASS-7", 0.55)
    with pytest.raises(InputError):
        refractive_index("FOO:N-BK7", 0.55)


def test_toml_options_curvature_inf_and_defaults():
    text = MINI.replace("radius = -80.0", "curvature = -0.0125")
    lens, margin = parse_lens_toml(text, "x.toml")
    assert lens.surfaces[1].radius == pytest.approx(-80.0)
    assert margin == 0.0 and lens.wavelengths_um == (0.5875618,) and lens.field_angles_deg == (0.0,)
    flat, _ = parse_lens_toml(MINI.replace("radius = -80.0", 'radius = "inf"'), "x.toml")
    assert math.isinf(flat.surfaces[1].radius)


@pytest.mark.parametrize("edit, field, line", [
    (("thickness = 90.0", "thickness = 90.0\ncolour = 3"), "surface[2].colour", 14),
    (("radius = 50.0", "radius = 50.0\ncurvature = 0.02"), "surface[1]", None),
    (("radius = 50.0", 'radius = "big"'), "surface[1].radius", 6),
    (("entrance_pupil_diameter = 10.0", "entrance_pupil_diameter = -1"), "aperture.entrance_pupil_diameter", 3),
    (('name = "singlet"', 'name = "singlet"\nunits = "inch"'), "units", 3),
])
def test_toml_schema_errors_name_field_and_line(edit, field, line):
    with pytest.raises(InputError) as err:
        parse_lens_toml(MINI.replace(*edit), "x.toml")
    assert err.value.field == field
    if line is not None:
        assert err.value.line == line
    assert err.value.file == "x.toml" and err.value.valid


def test_malformed_toml_names_the_line():
    with pytest.raises(InputError) as err:
        parse_lens_toml(MINI.replace("thickness = 6.0", "thickness = = 6.0"), "x.toml")
    assert err.value.line == 7


@pytest.mark.parametrize("edit, field, words", [
    (("thickness = 6.0", "thickness = -2.0"), "surface[1].thickness", "glass thickness"),
    (("stop = true\n", ""), "surface[].stop", "stop"),
    (('material = "N-BK7"', 'material = "N-BK77"'), "surface[1].material", "unknown glass"),
    (("radius = 50.0", "radius = 50.0\nclear_semi_diameter = 60.0"), "surface[1].radius", "smaller than"),
    (("thickness = 6.0", "thickness = 0.2"), "surface[1].thickness", "cross"),
    (("radius = -80.0\nthickness = 90.0", "radius = -80.0\nthickness = -2.0\nmaterial = \"N-SF6\""),
     "surface[2].thickness", "virtual"),   # an image in glass is allowed, not one before its face
])
def test_physical_checks_are_input_errors(tmp_path, edit, field, words):
    p = tmp_path / "lens.toml"
    text = MINI.replace(*edit)
    assert text != MINI
    p.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_lens(p)
    assert err.value.field == field
    assert words in err.value.paragraph()
    assert err.value.file == str(p)
    if field.startswith("surface[1].") and field != "surface[1].radius":
        key = field.split(".")[1]
        assert text.splitlines()[err.value.line - 1].startswith(key)   # the line of the offending key


def test_radius_too_small_for_the_automatic_beam(tmp_path):
    p = tmp_path / "lens.toml"
    p.write_text(MINI.replace("10.0 }", "30.0 }").replace("radius = 50.0", "radius = 14.0")
                 .replace("thickness = 6.0", "thickness = 12.0"), encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_lens(p)
    assert err.value.field == "surface[1].radius"


def test_a_design_folder_means_its_lens_file(examples):
    folder = examples["double_gauss"].parent
    assert load_lens(folder) == load_lens(examples["double_gauss"])
    assert paraxial(load_lens(folder)).f_number == pytest.approx(7.0)
