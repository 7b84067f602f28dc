"""`lensmount init --lens` where the glass, not the seats, sets the limit.

A Cooke triplet whose rims are OpticStudio's automatic ones (fixed clear semi-diameters, MEMA automatic
with a 0.14 mm chip zone): every rim sits 0.14 mm outside its clear aperture, less than the chamfer and
the seat's contact need, so widening one element only moves the refusal to the next; init widens every
rim by one margin. A fast Petzval whose front element's faces cross inside the beam of its full field:
init sizes the element to what its glass allows and states the vignetting per field that costs, and
`init --allow-vignetting` builds that mount.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from tests.cad.test_init_builds import COOKE, assert_init_hands_over_a_mount_that_builds_or_refuses

CHIP_ZONE = 0.14


def tight_triplet(path: Path) -> Path:
    """The Cooke triplet with each lens face's DIAM fixed at the real beam's height (rounded up to
    10 µm) and its MEMA automatic with a chip zone: rims CHIP_ZONE outside the clear aperture."""
    from lensmount.design.lens import load_lens

    beam = load_lens(COOKE).surfaces
    blocks = re.split(r"(?m)^(?=SURF )", COOKE.read_text())
    for k, block in enumerate(blocks):
        m = re.match(r"SURF (\d+)", block)
        if m is None or not 1 <= int(m.group(1)) <= len(beam) or "STOP" in block:
            continue
        clear = np.ceil(beam[int(m.group(1)) - 1].clear_semi_diameter * 100) / 100
        block = re.sub(r"  DIAM \S+ 0 ", f"  DIAM {clear:.2f} 1 ", block)
        blocks[k] = block.replace("  POPS", f"  MEMA {clear + CHIP_ZONE:.2f} 0\n  OEMA {CHIP_ZONE}\n  POPS", 1)
    path.write_text("".join(blocks))
    return path


def test_tight_triplet_rims_sit_the_chip_zone_outside_the_clear_aperture_and_one_wider_rim_is_not_enough(tmp_path):
    from lensmount.cad.mount_search import alternatives, refusal
    from lensmount.cad.starter import _mount
    from lensmount.design.lens import load_lens

    p = load_lens(tight_triplet(tmp_path / "tight.zmx"))
    for g in p.lens_groups():
        rim = max(p.surfaces[i].mechanical_semi_diameter or 0.0 for i in g)
        assert rim - max(p.surfaces[i].clear_semi_diameter for i in g) == pytest.approx(CHIP_ZONE, abs=1e-9)
    mount = _mount(p, "tight", True)
    first = refusal(p, mount)
    assert first is not None and "beyond the edge chamfer" in first.message
    # one element's rim wider (the planner's own alternative): the same fault moves to another element's face
    wider = [(what, alt) for what, alt in alternatives(p, mount, first) if re.fullmatch(r"element \d's rim .*", what)
             and float(re.search(r"rim ([\d.]+)", what).group(1)) > float(re.search(r"was ([\d.]+)", what).group(1))]
    assert wider
    for what, alt in wider:
        again = refusal(p, alt)
        assert again is not None and "beyond the edge chamfer" in again.message, what
        assert again.message.split(":")[0] != first.message.split(":")[0], what   # "surface N": another face


def test_every_rim_enlarged_by_one_margin_builds_the_tight_triplet(tmp_path):
    from lensmount.cad.mount_search import refusal
    from lensmount.cad.starter import _wider_rims
    from lensmount.design.lens import load_lens

    p = load_lens(tight_triplet(tmp_path / "tight.zmx"))
    mount = next(_wider_rims(p, "tight", ()))
    rims = mount["lens_edge"]["semi_diameter_mm"]
    assert sorted(rims) == ["1", "2", "3"]    # every element, the file's rims set aside
    edge = mount["lens_edge"]
    for (number, rim), g in zip(sorted(rims.items()), p.lens_groups()):
        clear = max(p.surfaces[i].clear_semi_diameter for i in g)
        assert rim - edge["chamfer_mm"] > clear + edge["contact_margin_mm"]   # the seat's contact inside the chamfer
    assert refusal(p, mount) is None


@pytest.mark.slow   # init's search, then the widened rims, then regenerate's solids: ~25 s
def test_init_builds_a_mount_for_the_tight_triplet(tmp_path):
    assert assert_init_hands_over_a_mount_that_builds_or_refuses(tight_triplet(tmp_path / "tight.zmx"), tmp_path) == 0


# A 48 mm f/1.34 Petzval-like lens: a thin, strongly curved front crown whose faces meet 19.96 mm from the axis,
# inside the 20.25 mm the beam of its 6° field reaches (the on-axis beam: 18 mm), the stop in the air behind it
PETZVAL = [(52.0, 4.75, "N-LAK9"), (-260.0, 12.0, None), (None, 10.0, None), (60.0, 7.0, "N-LAK9"),
           (-90.0, 2.0, None), (-45.0, 2.0, "SF5"), (-400.0, 30.0, None)]
PETZVAL_STOP, PETZVAL_EPD, PETZVAL_FIELDS = 3, 36.0, (0.0, 4.0, 6.0)


def petzval(path: Path, front_thickness: float = PETZVAL[0][1]) -> Path:
    """The lens as lens.toml; `front_thickness`: the front crown's centre thickness, mm."""
    rows = [(PETZVAL[0][0], front_thickness, PETZVAL[0][2])] + PETZVAL[1:]
    text = ['name = "fast Petzval"', f"aperture = {{ entrance_pupil_diameter = {PETZVAL_EPD} }}", "",
            "[wavelengths]", "values_um = [0.4861327, 0.5875618, 0.6562725]", "primary = 2", "",
            "[field]", f"angles_deg = [{', '.join(str(f) for f in PETZVAL_FIELDS)}]"]
    for k, (radius, thickness, glass) in enumerate(rows, start=1):
        text += ["", "[[surface]]", f"radius = {radius}" if radius else 'radius = "inf"', f"thickness = {thickness}"]
        text += [f'material = "{glass}"'] if glass else []
        text += ["stop = true"] if k == PETZVAL_STOP else []
    path.write_text("\n".join(text) + "\n")
    return path


def _sag(radius: float, h: float) -> float:
    return radius - np.sign(radius) * np.sqrt(radius * radius - h * h)


def test_the_petzval_front_element_crosses_inside_its_beam_and_the_import_alone_refuses_it(tmp_path):
    from lensmount.design.lens import load_lens
    from lensmount.errors import InputError

    (r1, t, _), (r2, _, _) = PETZVAL[:2]
    edge = lambda h: t - _sag(r1, h) + _sag(r2, h)   # noqa: E731  glass between the spheres at height h
    assert edge(PETZVAL_EPD / 2) > 0.0 > edge(20.25)    # crossed outside the on-axis beam, inside the field's
    with pytest.raises(InputError) as refused:
        load_lens(petzval(tmp_path / "lens.toml"))
    assert "cross each other" in refused.value.detail


def test_a_mount_that_allows_vignetting_loads_the_element_sized_by_its_glass(tmp_path):
    """The design folder loads the lens as its mount says: the element edged where its faces are the
    mount's least edge apart (checked on the spheres' own sag), the vignetting per field in its warnings,
    none at 0° (the clip lies outside the on-axis beam, EPD/2 on the first face)."""
    from lensmount.design.edges import clip_gap
    from lensmount.design.folder import load_design
    from lensmount.errors import InputError

    design = tmp_path / "design"
    design.mkdir()
    petzval(design / "lens.toml")
    (design / "mount.toml").write_text("[lens_edge]\nchamfer_mm = 0.1\n\n[checks]\nmin_thickness_mm = 0.3\n")
    with pytest.raises(InputError):
        load_design(design)
    (design / "mount.toml").write_text("[lens_edge]\nchamfer_mm = 0.1\nallow_vignetting = true\n\n"
                                       "[checks]\nmin_thickness_mm = 0.3\n")
    d = load_design(design)
    assert clip_gap(d.mount) == pytest.approx(0.5)
    (r1, t, _), (r2, _, _) = PETZVAL[:2]
    h = d.prescription.surfaces[0].clear_semi_diameter
    assert t - _sag(r1, h) + _sag(r2, h) == pytest.approx(0.5, abs=1e-6)
    assert PETZVAL_EPD / 2 < h < 19.96
    (clip,) = d.lens_clips
    assert clip.lost[0] == 0.0 and 0.0 < clip.lost[1] < clip.lost[2]   # more of the pupil lost further out
    assert len(d.lens_warnings) == 1 and "% at 6°" in d.lens_warnings[0]


# 0.35 mm thicker: the faces stay 0.2 mm apart at the 20.25 mm beam and meet 20.66 mm from the axis, outside it,
# closer than the mount's least edge (0.3 mm after two 0.1 mm chamfers) inside the beam: no seat finds its edge
NEAR = 5.1


def test_an_element_too_thin_inside_its_beam_is_sized_by_its_glass_when_the_mount_allows_vignetting(tmp_path):
    from lensmount.design.folder import load_design

    design = tmp_path / "design"
    design.mkdir()
    petzval(design / "lens.toml", NEAR)
    (design / "mount.toml").write_text("[lens_edge]\nchamfer_mm = 0.1\n\n[checks]\nmin_thickness_mm = 0.3\n")
    plain = load_design(design)
    assert not plain.lens_clips and plain.prescription.surfaces[0].clear_semi_diameter > 20.2   # the beam's own
    (design / "mount.toml").write_text("[lens_edge]\nchamfer_mm = 0.1\nallow_vignetting = true\n\n"
                                       "[checks]\nmin_thickness_mm = 0.3\n")
    d = load_design(design)
    (r1, _, _), (r2, _, _) = PETZVAL[:2]
    h = d.prescription.surfaces[0].clear_semi_diameter
    assert NEAR - _sag(r1, h) + _sag(r2, h) == pytest.approx(0.5, abs=1e-6)
    (clip,) = d.lens_clips
    assert clip.meet > clip.beam() > h and "come closer than 0.5 mm" in d.lens_warnings[0]


@pytest.mark.slow   # two inits (each a search and the solids), regenerate with its STEP export, check: ~90 s
@pytest.mark.parametrize("front", [PETZVAL[0][1], NEAR], ids=["faces-crossing", "faces-too-close"])
def test_init_states_what_the_glass_allows_and_builds_with_allow_vignetting(tmp_path, front):
    from tests.cad.test_init_builds import regenerate_refusal

    lens = petzval(tmp_path / "petzval.toml", front)
    design = tmp_path / "design"
    refused = CliRunner().invoke(app, ["init", str(design), "--lens", str(lens)])
    lines = refused.output.strip().splitlines()
    assert refused.exit_code == 2 and len(lines) == 1, refused.output
    assert "element 1 can be" in lines[0] and "% at 6°" in lines[0] and "--allow-vignetting" in lines[0]
    assert not design.exists()
    built = CliRunner().invoke(app, ["init", str(design), "--lens", str(lens), "--allow-vignetting"])
    assert built.exit_code == 0, built.output
    text = (design / "mount.toml").read_text()
    assert "allow_vignetting = true" in text and "% at 6°" in text.split("\nname")[0]   # stated in the header
    assert regenerate_refusal(design) is None
    assert CliRunner().invoke(app, ["regenerate", str(design), "--quiet"]).exit_code == 0
    checked = CliRunner().invoke(app, ["check", str(design)])
    assert checked.exit_code in (0, 1), checked.output
    assert "vignettes the designed pupil by" in checked.output and "% at 6°" in checked.output
