"""Line-of-sight hood vanes: with the construction's vanes no wall point the sun lights (at the
exclusion angle or beyond) can be seen from any point of the entrance aperture through the vane
openings; evenly spaced vanes of the same count leave such a wall. Checked by straight lines in
the meridional plane, independently of the construction (layout only, no CAD kernel)."""

import numpy as np
import pytest

from lensmount.cad.layout import plan
from lensmount.design.lens import load_lens
from lensmount.design.mount import parse_mount
from lensmount.validation import parse_toml


def _layout(examples_dir, placement, exclusion, count=None, example="double-gauss-360"):
    data = parse_toml((examples_dir / example / "mount.toml").read_text(), "mount.toml")
    data["vanes"]["placement"] = placement
    data["hood"]["exclusion_deg"] = exclusion
    if count is not None:
        data["vanes"]["count"] = count
    spec = parse_mount(data)
    p = load_lens(examples_dir / example / "lens.toml")
    return plan(p, spec), spec


def _lit_and_seen(layout, exclusion):
    """Wall z values (top wall, r = R) lit by the sun from below at >= exclusion and seen from the
    entrance aperture (first surface's clear aperture) through every vane opening between."""
    hood = layout.part("hood").template
    R, z0, z1 = hood.inner_radius, hood.z_front, hood.z_back
    vanes = [(v.template.z_front, v.template.z_front + v.template.thickness, v.template.inner_radius)
             for v in layout.parts if v.kind == "vane" and v.template.z_front < z1]
    a = layout.prescription.surfaces[0].clear_semi_diameter
    za = float(layout.part("lens-1").template.front_z(a))  # the clear aperture's rim
    zw = np.linspace(z0, z1, 2001)

    def clear(y_of_z, lo, hi):
        ok = np.ones(len(zw), bool)
        for f, b, r in vanes:
            for zv in (f, b):
                inside = (zv > lo) & (zv < hi)
                ok &= ~inside | (np.abs(y_of_z(zv)) <= r)
        return ok

    lit = np.zeros(len(zw), bool)
    for th in np.radians(np.linspace(exclusion, 89.0, 60)):
        # a sun ray reaching (R, zw) going up at angle th: y(z) = R - tan(th) (zw - z), from the mouth
        y = lambda z, th=th: R - np.tan(th) * (zw - z)  # noqa: E731
        lit |= clear(y, z0 - 1e-9, zw) & (np.abs(y(z0)) <= R)
    seen = np.zeros(len(zw), bool)
    for ya in np.linspace(-a, a, 41):
        y = lambda z, ya=ya: ya + (R - ya) * (za - z) / (za - zw)  # noqa: E731
        seen |= clear(y, zw, za)
    return zw[lit & seen]


@pytest.mark.parametrize("example,exclusion", [("cooke-triplet", 25.0), ("double-gauss-360", 10.0)])
def test_line_of_sight_vanes_hide_every_lit_wall(examples_dir, example, exclusion):
    """The construction hides every lit wall; the example's own evenly spaced vanes (2 and 3) do not.
    Even spacing with the construction's count (6 and 21 here) hides it too: on these hoods the
    sun past the first vane reaches every bay at any exclusion angle, so what the construction
    adds is the count (cooke: 5 even vanes still leave lit wall in sight)."""
    los, spec = _layout(examples_dir, "line-of-sight", exclusion, example=example)
    n = sum(v.kind == "vane" and v.template.z_front < 0 for v in los.parts)
    bad = _lit_and_seen(los, exclusion)
    assert len(bad) == 0, f"{n} line-of-sight vanes leave lit wall seen at z = {bad[:5]}"
    even, even_spec = _layout(examples_dir, "even", exclusion, example=example)
    assert even_spec.vanes.count < n
    assert len(_lit_and_seen(even, exclusion)) > 0, "the example's even vanes hide the wall too"
    if example == "cooke-triplet":
        fewer, _ = _layout(examples_dir, "even", exclusion, count=n - 1, example=example)
        assert len(_lit_and_seen(fewer, exclusion)) > 0
