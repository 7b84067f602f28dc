"""A cemented group whose crown is too thin at the group's rim is stepped: the crown edged to its clear
semi-diameter plus a bevel, the group seated on the flint's cemented face outside it (docs/mount-toml.md).

US 583,336 (the original double Gauss, tests/optics/corpus): each crown (R 16.20 / -19.67 mm, 2.313 mm of
N-BAK1) is 0.266 mm thick at its fixed 5.94 mm clear semi-diameter, and no rim a seat could touch outside
the light is thicker than 0.05 mm. The numbers below come from the patent's radii by the sphere's sag.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

CORPUS = Path(__file__).resolve().parents[1] / "optics" / "corpus"
R_CROWN, R_CEMENT, T_CROWN, CLEAR = 1 / 6.174554660245130200e-2, -1 / 5.085176709890669400e-2, 2.313, 5.94


def _sag(radius: float, h: float) -> float:
    return radius - math.copysign(math.sqrt(radius * radius - h * h), radius)


def test_retainer_face_leaves_the_lens_on_either_side():
    from lensmount.templates.retainer import Retainer

    front = Retainer(5.0, 10.0, 0.1, -1, 8.0, 1.0)     # in front of the lens (which lies at larger z)
    back = Retainer(5.0, 10.0, 0.1, +1, 8.0, 1.0)
    assert front.contact_face_z(7.0) == pytest.approx(9.8)
    assert back.contact_face_z(7.0) == pytest.approx(10.2)


@pytest.mark.slow  # the corpus lens's real-ray apertures, the planner and its profile checks: ~6 s
def test_a_thin_edged_crown_is_stepped_and_the_group_seated_on_its_flint():
    from lensmount.cad.checks import check_layout
    from lensmount.cad.layout import plan
    from lensmount.design.lens import load_lens
    from lensmount.design.mount import parse_mount
    from lensmount.cad.starter import starter_mount

    p = load_lens(CORPUS / "US00583336-2-scaled.zmx")
    assert _sag(R_CROWN, CLEAR) - _sag(R_CEMENT, CLEAR) == pytest.approx(T_CROWN - 0.266, abs=5e-4)
    mount, error = starter_mount(p, "US583336")
    assert error is None, error
    assert mount["lens_edge"]["flat_faces"] == [6, 8]   # the deep inner faces beside the diaphragm
    spec = parse_mount(mount)
    layout = plan(p, spec)
    check_layout(layout, spec, {part.name: part.template.segments() for part in layout.parts})

    crown, flint = layout.part("lens-2").template, layout.part("lens-3").template
    r_s, bevel = crown.outer_radius, crown.front_chamfer
    assert r_s == pytest.approx(CLEAR + bevel, abs=1e-12) and crown.back_chamfer == 0.0
    assert 0.0 < bevel <= spec.lens_edge.chamfer_mm
    # edge by hand: centre thickness + cemented face's sag - front face's sag - the bevel, at the rim
    edge = T_CROWN + _sag(R_CEMENT, r_s) - _sag(R_CROWN, r_s) - bevel
    assert crown.edge_thickness() == pytest.approx(edge, abs=1e-9)
    assert edge == pytest.approx(spec.lens_edge.stepped_min_edge_mm, abs=1e-6)   # the bevel was cut to it
    # the spacer from lens-1 touches the flint's cemented face (surface 5) outside the crown's rim
    touch = next(c for c in layout.contacts if c.lens == "lens-3" and c.surface == 4)
    assert touch.height == pytest.approx(r_s + spec.lens_edge.contact_margin_mm)
    assert flint.front_chamfer == spec.lens_edge.chamfer_mm and flint.outer_radius > touch.height
    assert any("lens-2: stepped" in n for n in layout.notes) and any("lens-5: stepped" in n for n in layout.notes)


def test_the_partners_bare_cemented_face_outside_the_step_is_ground_not_an_interface():
    """Outside a stepped crown the flint's cemented face meets air, not the crown: it must not be tagged
    as the crown/flint interface (the tracer would refract there with the crown's index)."""
    from lensmount.cad.lens_groups import lens_group
    from lensmount.templates.lens_element import OpticalFace

    faces = [OpticalFace(0, 0.0, 1 / R_CROWN), OpticalFace(1, T_CROWN, 1 / R_CEMENT),
             OpticalFace(2, T_CROWN + 1.386, 1.137268281587626600e-1)]
    els, stepped = lens_group(faces, 6.5, 0.068, [CLEAR, CLEAR, 4.5], 0.3, 0.2)
    assert stepped == (0,)
    crown, flint = els
    segs = flint.segments()
    optical = [s for s in segs if s.role == "optical" and s.surface == 1]
    ground = [s for s in segs if s.role == "bevel" and abs(s.start[0] - crown.outer_radius) < 1e-12]
    assert max(p[0] for s in optical for p in s.points) == pytest.approx(crown.outer_radius, abs=1e-12)
    assert len(ground) == 1 and ground[0].end[0] == pytest.approx(6.5 - 0.068, abs=1e-12)
    # the ground annulus follows the cemented sphere (hand sag), it is not flattened
    r, z = ground[0].end
    assert z == pytest.approx(T_CROWN + _sag(R_CEMENT, r), abs=1e-12)
