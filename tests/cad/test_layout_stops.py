"""Where the stop of a real lens file sits, the layout still puts a diaphragm there
(public files of tests/optics/corpus, mounts from `lensmount init`'s starter).

References are the files' own numbers: a stop on surface 1 is crossed by the on-axis
ray at EPD/2 while that ray is still parallel to the axis, so the land's radius is
EPD/2 exactly; a stop surface of its own sits at the sum of the thicknesses before it.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from lensmount.cad.checks import check_layout
from lensmount.cad.layout import plan
from lensmount.design.lens import load_lens
from lensmount.design.mount import parse_mount
from lensmount.cad.starter import starter_mount

CORPUS = Path(__file__).resolve().parents[1] / "optics" / "corpus"


def _layout(name: str):
    p = load_lens(CORPUS / name)
    mount, why = starter_mount(p, name)
    assert why is None, why
    spec = parse_mount(mount)
    layout = plan(p, spec)
    check_layout(layout, spec, {part.name: part.template.segments() for part in layout.parts})
    return p, spec, layout


@pytest.mark.slow  # a starter mount is planned and checked twice (~10 s on the shared machine)
def test_stop_on_a_singlet_front_face_gets_a_coned_diaphragm_against_the_barrel_lip():
    p, spec, layout = _layout("thorlabs-LA1131-A.zmx")   # STOP on SURF 1, ENPD 22.86, CURV 1/25.75
    dia = layout.part("diaphragm").template
    assert dia.inner_radius == pytest.approx(22.86 / 2, rel=1e-9)
    lens = layout.part("lens-1").template
    z0, z1 = dia.z_range()
    # in front of the glass by the clearance where the land is, and nothing else in front of lens 1
    assert z1 <= float(lens.front_z(dia.inner_radius)) - spec.seats.clearance_mm + 1e-9
    names = [part.name for part in layout.parts]
    assert not any(n.startswith(("retainer", "spacer")) for n in names) and "barrel" in names


@pytest.mark.slow
def test_stop_plane_next_to_a_concave_face_keeps_the_land_on_the_stop_plane():
    p, spec, layout = _layout("optiland-lens1.zmx")   # stop 0.754 mm behind lens 2's rear (R 10.18)
    dia = layout.part("diaphragm").template
    assert dia.z_stop == pytest.approx(5.514 + 2.638 + 1.017 + 0.754, abs=2e-3)   # the file's DISZ
    # no spacer between lens 2 and the diaphragm: the plate follows lens 2's face instead
    lens2_front = 5.514 + 2.638
    spacers = [part.template for part in layout.parts if part.kind == "spacer"]
    assert not any(s.front_z > lens2_front and s.back_z <= dia.z_stop for s in spacers)
