"""A retainer ring on an inner element (`seats.element.N = "retainer"`): a barrel shoulder holds
the element in front, a ring holds element N; the layout passes every check (interference, glass
gaps, beam), and (slow) it regenerates into valid STEP with the pupil set by the diaphragm."""

from pathlib import Path

import pytest

from lensmount.cad.checks import check_layout
from lensmount.cad.layout import plan
from lensmount.design.lens import load_lens
from lensmount.design.mount import parse_mount
from lensmount.validation import parse_toml


def _spec(examples_dir: Path):
    data = parse_toml((examples_dir / "double-gauss-360" / "mount.toml").read_text(), "mount.toml")
    data["seats"]["element"] = {2: "retainer"}
    return parse_mount(data)


def test_retainer_holds_element_2_and_a_shoulder_element_1(examples_dir):
    spec = _spec(examples_dir)
    layout = plan(load_lens(examples_dir / "double-gauss-360" / "lens.toml"), spec)
    held = {(c.part, c.lens) for c in layout.contacts}
    assert ("retainer-2", "lens-2") in held and ("barrel", "lens-1") in held
    assert not any(c.part.startswith("spacer") and c.lens in ("lens-1", "lens-2") for c in layout.contacts)
    ring = layout.part("retainer-2").template
    assert ring.side == -1 and ring.contact_z == pytest.approx(float(layout.part("lens-2").template.front_z(ring.contact_r)))
    check_layout(layout, spec, {pp.name: pp.template.segments() for pp in layout.parts})


def test_no_room_for_shoulder_and_ring_is_reported(examples_dir):
    from lensmount.errors import GeometryError

    data = parse_toml((examples_dir / "double-gauss-360" / "mount.toml").read_text(), "mount.toml")
    data["seats"]["element"] = {6: "retainer"}  # 5.7 mm between lens 5 and lens 6 at the contacts
    data["retainer"]["thickness_mm"] = 4.0  # a 2 mm shoulder and a 4 mm ring do not fit
    with pytest.raises(GeometryError) as err:
        plan(load_lens(examples_dir / "double-gauss-360" / "lens.toml"), parse_mount(data))
    assert err.value.field == "seats.element.6"


@pytest.mark.slow
def test_inner_retainer_regenerates(tmp_path, design_copier):
    from lensmount.cad.pipeline import regenerate
    from lensmount.mesh import TaggedMesh
    from lensmount.cad.pupil import realised_entrance_pupil

    d = design_copier("double-gauss-360", tmp_path / "d")
    (d / "mount.toml").write_text((d / "mount.toml").read_text().replace(
        'default = "spacer"', 'default = "spacer"\nelement = { 2 = "retainer" }'))
    manifest = regenerate(d, tmp_path / "out")  # interference, glass-gap and beam checks
    assert "retainer-2" in {p.name for p in manifest.parts}
    pupil = realised_entrance_pupil(load_lens(d / "lens.toml"), TaggedMesh.load(tmp_path / "out" / "mesh.npz"))
    assert abs(pupil.relative_error) < 5e-3 and set(pupil.limited_by) == {"diaphragm"}
