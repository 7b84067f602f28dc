"""Glass and metal touch where they are meant to and keep the designed clearance elsewhere:
no sub-micrometre sliver between a lens face and a seat, shoulder or barrel step (on the reference
the barrel step once lay 0.07 µm from lens 6 at r = 31.0 mm, and spacer 1 ran within
0.05 µm of lens 1's concave face for 0.44 mm)."""

import dataclasses

import numpy as np
import pytest

from lensmount.cad.checks import glass_gaps, slivers
from lensmount.templates.profile import outline
from lensmount.cad.layout import plan
from lensmount.design.lens import load_lens
from lensmount.design.mount import load_mount


def _distance(p, poly):
    a, b = poly, np.roll(poly, -1, axis=0)
    t = np.clip(((p - a) * (b - a)).sum(1) / np.maximum(((b - a) ** 2).sum(1), 1e-300), 0.0, 1.0)
    return float(np.hypot(*(a + t[:, None] * (b - a) - p).T).min())


def _layout(examples_dir, name, reference_layout):
    if name == "double-gauss-360":
        layout, spec = reference_layout  # built once per session
    else:
        spec = load_mount(examples_dir / name / "mount.toml")
        layout = plan(load_lens(examples_dir / name / "lens.toml"), spec)
    return layout, spec, {p.name: p.template.segments() for p in layout.parts}


@pytest.mark.parametrize("example", ["cooke-triplet", "double-gauss-360"])
def test_glass_and_metal_touch_or_keep_the_clearance(examples_dir, example, reference_layout):
    layout, spec, segs = _layout(examples_dir, example, reference_layout)
    c = spec.seats.clearance_mm
    wedge = np.tan(np.radians(spec.seats.wedge_deg))
    gaps = glass_gaps(layout, spec, segs)
    # every designed contact touches: the glass point at the contact height lies on the part
    for ct in layout.contacts:
        lens = layout.part(ct.lens).template
        face = lens.front_z if ct.surface == lens.front.index else lens.back_z
        point = np.array([ct.height, float(face(ct.height))])
        assert _distance(point, outline(segs[ct.part])) < 1e-6, f"{ct.part} does not touch {ct.lens}"
    for lens, part, r, z, gap, dist in gaps:
        # the clearance (>= 0.5 c perpendicular: it is set along the axis), or a wedge opening from a contact
        assert gap >= min(0.5 * c, 0.5 * wedge * dist), (lens, part, r, z, gap, dist)
    far = [g[4] for g in gaps if g[5] > 1.0]
    assert not far or min(far) >= 0.5 * c
    assert slivers(layout, spec, segs) == []


def test_a_step_a_fraction_of_a_micrometre_off_the_glass_is_a_sliver(examples_dir, reference_layout):
    """The measurement can fail: put the barrel step in front of lens 6 back on the glass's
    corner height less 0.5 µm, as main had it, and it names lens-6 and the barrel."""
    layout, spec, segs = _layout(examples_dir, "double-gauss-360", reference_layout)
    barrel = layout.part("barrel").template
    lens6 = layout.part("lens-6").template
    bore = list(barrel.bore)
    k = next(i for i, (r, z) in enumerate(bore) if abs(z - (float(lens6.front_z(r)) - spec.seats.clearance_mm)) < 1e-9
             and r < lens6.outer_radius)
    z_glass = float(lens6.front_z(bore[k][0])) - 5e-4
    bore[k] = (bore[k][0], z_glass)
    bore[k + 1] = (bore[k + 1][0], z_glass)
    segs["barrel"] = dataclasses.replace(barrel, bore=tuple(bore)).segments()
    bad = slivers(layout, spec, segs)
    assert bad and {(b[0], b[1]) for b in bad} == {("lens-6", "barrel")}
    assert min(b[4] for b in bad) < 1e-3
