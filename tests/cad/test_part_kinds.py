"""The planner's part kinds: the built-in ones are registered stages like a plug-in's, sized by their own tables."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from lensmount.cad.layout import plan
from lensmount.cad.stages import PART_KINDS
from lensmount.design.lens import load_lens
from lensmount.design.mount import parse_mount
from lensmount.errors import InputError

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


def test_the_hood_and_the_housing_are_registered_kinds_placed_in_that_order(reference_layout):
    assert PART_KINDS.names()[:2] == ("hood", "housing")
    layout, _ = reference_layout
    kinds = [p.kind for p in layout.parts]
    around = kinds[kinds.index("hood"):]
    assert around == ["hood"] + ["vane"] * around.count("vane") + ["housing"]


def test_a_built_in_kind_takes_no_keys_in_the_kinds_table():
    data = tomllib.loads((EXAMPLE / "mount.toml").read_text()) | {"kinds": {"hood": {"length_mm": 50.0}}}
    with pytest.raises(InputError) as err:
        plan(load_lens(EXAMPLE / "lens.toml"), parse_mount(data))
    assert err.value.field == "kinds.hood.length_mm"
