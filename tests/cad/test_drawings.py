"""Shop drawings beside the STEP files: every part's parts/NAME.svg parses as XML and
parts/NAME.dxf with ezdxf; the dimensions they carry equal the part's geometry as the
layout planned it (bores, lengths, land width, bevel, tolerances from mount.toml), and the
drawn half section spans the part's real extent."""

import math
import xml.etree.ElementTree as ET

import ezdxf
import pytest

SVG = "{http://www.w3.org/2000/svg}"


def _svg_texts(path):
    root = ET.parse(path).getroot()
    return [t.text for t in root.iter(f"{SVG}text")]


def _dxf(path):
    doc = ezdxf.readfile(path)
    msp = doc.modelspace()
    return doc, [e.dxf.text for e in msp.query("TEXT")]


def test_every_part_has_a_drawing_that_parses(reference):
    _, out, manifest = reference
    for part in manifest.parts:
        assert part.svg == f"parts/{part.name}.svg" and part.dxf == f"parts/{part.name}.dxf"
        texts = _svg_texts(out / part.svg)
        assert any(part.name in t for t in texts), part.name  # the title block names it
        _, dxf_texts = _dxf(out / part.dxf)
        assert sorted(dxf_texts) == sorted(texts), part.name  # one set of labels, both formats


def test_diaphragm_drawing_carries_its_bore_land_and_bevel(reference, reference_layout):
    """Bore = 2 × the layout's land radius (the designed pupil's edge ray), land width and bevel
    from mount.toml, with mount.toml's [drawing] tolerances."""
    _, out, _ = reference
    layout, spec = reference_layout
    dia = layout.part("diaphragm").template
    tol = spec.drawing
    want = {f"bore Ø{2 * dia.inner_radius:.3f} ±{tol.diameter_mm:g}",
            f"outside Ø{2 * dia.outer_radius:.3f} ±{tol.diameter_mm:g}",
            f"land {spec.diaphragm.land_mm:.3f} ±{tol.land_mm:g}",
            f"thickness {spec.diaphragm.thickness_mm:.3f} ±{tol.length_mm:g}",
            f"bevel {spec.diaphragm.bevel_angle_deg:.1f}° ±{tol.angle_deg:g}°"}
    assert want <= set(_svg_texts(out / "parts" / "diaphragm.svg"))
    assert want <= set(_dxf(out / "parts" / "diaphragm.dxf")[1])


def test_vane_and_barrel_dimensions_and_drawn_extent(reference, reference_layout):
    _, out, _ = reference
    layout, spec = reference_layout
    vane = layout.part("vane-1").template
    texts = set(_dxf(out / "parts" / "vane-1.dxf")[1])
    assert f"bore Ø{2 * vane.inner_radius:.3f} ±{spec.drawing.diameter_mm:g}" in texts
    assert f"land {spec.vanes.edge_width_mm:.3f} ±{spec.drawing.land_mm:g}" in texts
    barrel = layout.part("barrel").template
    zs = [z for _, z in barrel.bore]
    doc, texts = _dxf(out / "parts" / "barrel.dxf")
    assert f"length {max(zs) - min(zs):.3f} ±{spec.drawing.length_mm:g}" in texts
    assert f"outside Ø{2 * barrel.outer_radius:.3f} ±{spec.drawing.diameter_mm:g}" in texts
    for r in {r for (r, za), (rb, zb) in zip(barrel.bore[:-1], barrel.bore[1:]) if abs(r - rb) < 1e-9 and zb > za}:
        assert f"bore Ø{2 * r:.3f} ±{spec.drawing.diameter_mm:g}" in texts
    # the section on layer "profile": x from 0 to the barrel's length, y up to its outside radius
    from ezdxf import bbox

    box = bbox.extents(doc.modelspace().query('*[layer=="profile"]'))
    assert box.extmin.x == pytest.approx(0.0, abs=1e-6) and box.extmax.x == pytest.approx(max(zs) - min(zs), abs=1e-6)
    assert box.extmin.y == pytest.approx(min(r for r, _ in barrel.bore), abs=1e-6)
    assert box.extmax.y == pytest.approx(barrel.outer_radius, abs=1e-6)


def test_drawing_tolerances_are_mount_toml_fields(examples_dir):
    from lensmount.design.mount import parse_mount

    spec = parse_mount({"drawing": {"diameter_mm": 0.005, "land_mm": 0.002}})
    assert spec.drawing.diameter_mm == 0.005 and spec.drawing.length_mm == 0.05
    from lensmount.errors import InputError

    with pytest.raises(InputError, match="drawing"):
        parse_mount({"drawing": {"diameter_mm": -1.0}})


def test_every_built_in_kind_is_dimensioned_from_its_template():
    """Hood, housing, tube spacer, retainer, rear baffle: the values a turner needs, from the
    template's own numbers (no CAD kernel)."""
    from lensmount.cad.drawing import dimensions
    from lensmount.cad.plan import PartPlan
    from lensmount.design.mount import Drawing
    from lensmount.templates.hood import Hood
    from lensmount.templates.housing import Housing
    from lensmount.templates.rear_baffle import RearBaffle
    from lensmount.templates.retainer import Retainer
    from lensmount.templates.spacer import Spacer

    tol = Drawing()

    def values(template):
        return {d.name: round(d.value, 6) for d in dimensions(PartPlan("p", "k", "f", template), tol)}

    assert values(Hood(-120.0, -20.0, 30.0, 32.0, 25.0, 2.0)) == {
        "bore": 60.0, "outside": 64.0, "length": 100.0, "flange bore": 50.0, "flange": 2.0}
    assert values(Housing(10.0, 60.0, 20.0, 3.0, 15.0)) == {
        "bore": 40.0, "outside": 46.0, "length": 53.0, "depth": 50.0, "flange bore": 30.0}
    tube = values(Spacer(10.0, 5.0, 0.0, 9.0, 55.0, 0.0, 14.0, 12.0, 2.0))
    assert tube == {"front bore": 20.0, "rear bore": 18.0, "outside": 28.0, "length": 50.0, "tube bore": 24.0,
                    "lip": 2.0}
    ring = Retainer(10.0, 5.0, 0.0, -1, 14.0, 3.0, 11.0)
    assert values(ring) == {"contact bore": 20.0, "far bore": 22.0, "outside (thread)": 28.0, "thickness": 3.0}
    assert values(RearBaffle(((12.0, 100.0), (10.0, 150.0)), 15.0)) == {
        "outside": 30.0, "length": 50.0, "front bore": 24.0, "rear bore": 20.0}


def test_catadioptric_parts_are_dimensioned_from_their_templates():
    """A mirror blank with a hole, a cell and a spider cell (lensmount.cad.catadioptric)."""
    from lensmount.cad.drawing import dimensions
    from lensmount.cad.plan import PartPlan
    from lensmount.design.mount import Drawing
    from lensmount.templates.cell import Cell, SpiderCell
    from lensmount.templates.lens_element import OpticalFace
    from lensmount.templates.mirror import MirrorElement

    tol = Drawing()

    def values(template):
        return {d.name: round(d.value, 6) for d in dimensions(PartPlan("p", "k", "f", template), tol)}

    flat = MirrorElement(OpticalFace(1, 10.0), None, 20.0, 3.0, front_coated=18.0, back_z_flat=16.0)
    assert values(flat) == {"edge": 40.0, "edge thickness": 6.0, "hole": 6.0, "R1": math.inf}
    ring = ((5.0, 0.0), (12.0, 0.0), (12.0, 4.0), (5.0, 4.0))
    assert values(Cell(ring)) == {"outside": 24.0, "bore": 10.0, "length": 4.0}
    assert values(SpiderCell(ring, 3, 0.5, 30.0, 0.0, 4.0)) == {"outside": 24.0, "bore": 10.0, "length": 4.0,
                                                               "vane tips": 60.0}
