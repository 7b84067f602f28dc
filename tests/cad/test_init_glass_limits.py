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
    from lensmount.cad.mount_search import refusal
    from lensmount.cad.starter import _mount
    from lensmount.design.lens import load_lens

    p = load_lens(tight_triplet(tmp_path / "tight.zmx"))
    for g in p.lens_groups():
        rim = max(p.surfaces[i].mechanical_semi_diameter or 0.0 for i in g)
        assert rim - max(p.surfaces[i].clear_semi_diameter for i in g) == pytest.approx(CHIP_ZONE, abs=1e-9)
    first = refusal(p, _mount(p, "tight", True))
    assert first is not None and "beyond the edge chamfer" in first.message


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
