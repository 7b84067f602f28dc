"""Glass seat: two elements whose faces meet just outside the light sit on each other, no part between.

US 8,427,765 (tests/optics/corpus): lens-3's rear face (R -53.59 mm) and lens-4's front face
(R -37.47 mm) are 0.22 mm apart on the axis and meet at h = 7.325 mm, inside surface 8's file
semi-diameter (7.53 mm) but outside the light surface 7's 7.0 mm aperture lets through.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from scipy.optimize import brentq

from lensmount.cad.layout import plan
from lensmount.design.lens import load_lens
from lensmount.design.mount import parse_mount
from lensmount.cad.starter import starter_mount

CORPUS = Path(__file__).resolve().parents[1] / "optics" / "corpus"


def _sag(radius: float, h: float) -> float:
    return radius - math.copysign(math.sqrt(radius * radius - h * h), radius)


@pytest.mark.slow  # ~7 s on the shared machine: the patent's glass catalogues, the starter's checks, the layout
def test_lens_3_rests_its_rim_on_lens_4_where_the_faces_meet():
    # by hand, from the patent's numbers: where the 0.22 mm air gap closes
    meet = brentq(lambda h: 0.22 + _sag(-37.47, h) - _sag(-53.59, h), 6.0, 7.5)
    assert meet == pytest.approx(7.3253, abs=1e-4)

    p = load_lens(CORPUS / "US08427765-1.zmx")
    mount, error = starter_mount(p, "US08427765-1")
    assert error is None
    assert mount["seats"]["element"]["4"] == "glass"
    chamfer = mount["lens_edge"]["chamfer_mm"]
    assert mount["lens_edge"]["semi_diameter_mm"]["3"] == pytest.approx(meet + chamfer, abs=2e-3)

    layout = plan(p, parse_mount(mount))
    assert not [c for c in layout.contacts if c.lens == "lens-3" and c.surface == 6]   # nothing on its rear
    seat = [c for c in layout.contacts if c.lens == "lens-4" and c.surface == 7]
    assert [(c.part, round(c.height, 3)) for c in seat] == [("lens-3", round(meet, 3))]
    assert seat[0].height > seat[0].clear                      # outside the light there
    assert seat[0].clear < 7.53                                # the light, not the file's DIAM
    lens3, lens4 = layout.part("lens-3").template, layout.part("lens-4").template
    rim = lens3.outer_radius - lens3.back_chamfer
    assert float(lens4.front_z(rim)) - float(lens3.back_z(rim)) == pytest.approx(0.0, abs=2e-3)   # they touch
