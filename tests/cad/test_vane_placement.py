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
    if placement == "line-of-sight":
        data["vanes"].pop("count")  # the construction's own number: a count there is an error
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
    front = layout.part("lens-1").template.front_z  # the first surface: a convex one bulges toward the vanes
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
        za = float(front(abs(ya)))
        y = lambda z, ya=ya, za=za: ya + (R - ya) * (za - z) / (za - zw)  # noqa: E731
        seen |= clear(y, zw, za)
    return zw[lit & seen]


@pytest.mark.parametrize("example,exclusion,count", [("cooke-triplet", 25.0, 5), ("double-gauss-360", 10.0, 12)])
def test_line_of_sight_vanes_hide_every_lit_wall(examples_dir, example, exclusion, count):
    """The construction hides every lit wall; evenly spaced vanes of the same count do not, nor do
    the examples' own 2 and 3. The count (5 and 12 here) is the construction's: a sun ray behind a
    vane has passed every vane before it, so deep in the hood only shallow rays arrive and the wall
    they light starts far behind the vane; the gaps widen and fewer vanes do."""
    los, spec = _layout(examples_dir, "line-of-sight", exclusion, example=example)
    n = sum(v.kind == "vane" and v.template.z_front < 0 for v in los.parts)
    assert n == count
    bad = _lit_and_seen(los, exclusion)
    assert len(bad) == 0, f"{n} line-of-sight vanes leave lit wall seen at z = {bad[:5]}"
    even, even_spec = _layout(examples_dir, "even", exclusion, example=example)
    assert even_spec.vanes.count < n
    assert len(_lit_and_seen(even, exclusion)) > 0, "the example's even vanes hide the wall too"
    same, _ = _layout(examples_dir, "even", exclusion, count=n, example=example)
    assert len(_lit_and_seen(same, exclusion)) > 0, f"{n} even vanes hide the wall too"


def test_a_count_under_line_of_sight_placement_is_an_error_naming_the_key(examples_dir):
    """`count` is not silently ignored under line-of-sight placement (the default): otherwise
    `sweep --param mount.vanes.count=3,5,7` would build three identical mounts."""
    from lensmount.errors import InputError

    text = (examples_dir / "double-gauss-360" / "mount.toml").read_text().replace(
        'placement = "even"', 'placement = "line-of-sight"')
    with pytest.raises(InputError) as err:
        parse_mount(parse_toml(text, "mount.toml"), file="mount.toml", text=text)
    e = err.value
    assert e.field == "vanes.count" and "count = 3" in str(e) and 'placement = \"even\"' in e.valid
    assert text.splitlines()[e.line - 1].startswith("count = 3")
    # Without the key, or with even placement, or explicit positions, it reads.
    parse_mount(parse_toml(text.replace("count = 3 ", "# count"), "mount.toml"))
    parse_mount(parse_toml(text.replace('placement = "line-of-sight"', 'placement = "even"'), "mount.toml"))
