"""Parts of two revisions are matched by kind and place along the axis, never by the number in their name."""

import shutil

import pytest

from lensmount.analysis.part_match import match_parts
from lensmount.loop.regenerate import RegenerateOptions, regenerate
from lensmount.mesh import TaggedMesh
from tests.loop.runs import EXAMPLE


def part(kind, z0, z1, r0, r1):
    return {"kind": kind, "z_mm": [z0, z1], "r_mm": [r0, r1]}


def test_a_part_that_moved_a_little_or_grew_is_the_same_part():
    old = {"spacer-1": part("spacer", 30.0, 36.0, 39.0, 40.6), "spacer-2": part("spacer", 96.0, 150.0, 17.5, 31.0),
           "retainer-1": part("retainer", 10.0, 12.0, 40.0, 44.0), "hood": part("hood", -100.0, 0.0, 58.0, 60.0)}
    new = {"spacer-1": part("spacer", 30.4, 36.4, 39.0, 40.6), "spacer-2": part("spacer", 96.4, 150.0, 17.5, 31.0),
           "retainer-1": part("retainer", 10.0, 13.5, 40.0, 44.0), "hood": part("hood", -80.0, 0.0, 58.0, 60.0)}
    m = match_parts(old, new, [], [])
    assert sorted(m.pairs) == sorted((n, n) for n in old) and m.removed == m.added == []


def test_a_part_inserted_between_others_is_the_one_added_and_the_rest_keep_their_partners():
    old = {"spacer-1": part("spacer", 30.0, 36.0, 39.0, 40.6), "spacer-2": part("spacer", 96.0, 150.0, 17.5, 31.0)}
    new = {"spacer-1": part("spacer", 30.0, 36.0, 39.0, 40.6), "spacer-2": part("spacer", 60.0, 70.0, 30.0, 35.0),
           "spacer-3": part("spacer", 96.1, 150.0, 17.5, 31.0)}
    m = match_parts(old, new, [], [])
    assert sorted(m.pairs) == [("spacer-1", "spacer-1"), ("spacer-2", "spacer-3")]
    assert m.added == ["spacer-2"] and m.removed == []


def test_parts_of_different_kinds_are_never_the_same_part():
    old = {"my-ring": part("retainer", 10.0, 12.0, 40.0, 44.0)}
    new = {"my-ring": part("spacer", 10.0, 12.0, 40.0, 44.0)}
    m = match_parts(old, new, [], [])
    assert m.pairs == [] and m.removed == ["my-ring"] and m.added == ["my-ring"]


def test_runs_without_extents_and_channels_that_are_no_parts_match_by_name():
    m = match_parts(None, {"vane-1": part("vane", 0, 1, 20, 30)}, ["vane-1", "direct"], ["vane-1", "direct"])
    assert sorted(m.pairs) == [("direct", "direct"), ("vane-1", "vane-1")] and m.removed == m.added == []
    m = match_parts({"vane-1": part("vane", 0, 1, 20, 30)}, {"vane-1": part("vane", 0, 1, 20, 30)},
                    ["vane-1", "ghosts"], ["vane-1"])
    assert m.pairs == [("vane-1", "vane-1")] and m.removed == ["ghosts"] and m.added == []


@pytest.mark.slow
def test_the_reference_mount_with_one_hood_vane_instead_of_three_loses_exactly_two_hood_vanes(tmp_path):
    """The layout's own meshes (vanes.count 3 -> 1): every part of the new mount is paired with an old part
    of identical extents, and the two removed are vanes inside the hood (in front of the first lens, z < 0)."""
    meshes = {}
    for count in (3, 1):
        design = tmp_path / f"vanes-{count}"
        shutil.copytree(EXAMPLE, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
        mount = design / "mount.toml"
        mount.write_text(mount.read_text().replace("count = 3 ", f"count = {count} ", 1))
        built = regenerate(RegenerateOptions(design))
        meshes[count] = TaggedMesh.load(built.folder / built.manifest.mesh).part_extents()
    old, new = meshes[3], meshes[1]
    m = match_parts(old, new, [], [])
    assert m.added == [] and len(m.removed) == 2 and len(m.pairs) == len(new)
    assert all(old[a] == new[b] for a, b in m.pairs)
    assert all(old[n]["kind"] == "vane" and old[n]["z_mm"][1] < 0 for n in m.removed)
    assert any(a != b for a, b in m.pairs)  # the layout renumbered the vanes behind them
