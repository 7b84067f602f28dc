"""The part-kind recipe of docs/architecture.md, done once: knife-edged vanes in the detector housing,
added in a file of their own (knife_vanes.py) and its registration, placed by the planner, checked,
built and searched for as `init` searches for a mount, with nothing else in lensmount changed."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

import knife_vanes  # noqa: E402

from lensmount.cad.checks import check_layout  # noqa: E402
from lensmount.cad.layout import plan  # noqa: E402
from lensmount.cad.stages import PART_KINDS  # noqa: E402
from lensmount.design.lens import load_lens  # noqa: E402
from lensmount.design.mount import parse_mount  # noqa: E402
from lensmount.errors import InputError  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


@pytest.fixture
def knife_kind(monkeypatch):
    """The kind registered for one test (the registry is process-wide)."""
    monkeypatch.setattr(PART_KINDS, "_entries", dict(PART_KINDS._entries))
    knife_vanes.register()


@pytest.fixture(scope="module")
def lens():
    return load_lens(EXAMPLE / "lens.toml")


def mount(**kinds) -> dict:
    data = tomllib.loads((EXAMPLE / "mount.toml").read_text())
    return data | ({"kinds": kinds} if kinds else {})


def test_the_planner_places_a_registered_kind_from_its_table_clear_of_the_beam(knife_kind, lens):
    spec = parse_mount(mount(**{"knife-vane": {"count": 3}}))
    layout = plan(lens, spec)
    knives = [pp for pp in layout.parts if pp.kind == "knife-vane"]
    assert [k.name for k in knives] == ["knife-vane-1", "knife-vane-2", "knife-vane-3"]
    housing = layout.part("housing").template
    for k in knives:
        ring = k.template
        assert housing.z_front < ring.z - ring.thickness and ring.z <= lens.image_z - 2.0 + 1e-9
        assert ring.outer_radius == housing.inner_radius
        # the real rays of the full field, traced again at its faces and between, pass inside its knife edge
        assert layout.envelope.exact(np.linspace(ring.z - ring.thickness, ring.z, 9)).max() < ring.bore_radius
    # the profile checks (interference, beam, clear apertures, thickness) take the new parts as they are
    check_layout(layout, spec, {pp.name: pp.template.segments() for pp in layout.parts})
    # and every part planned without them is planned the same
    without = plan(lens, parse_mount(mount()))
    assert [pp for pp in layout.parts if pp.kind != "knife-vane"] == without.parts


def test_a_registered_kind_without_its_table_places_nothing(knife_kind, lens):
    assert [pp.kind for pp in plan(lens, parse_mount(mount())).parts].count("knife-vane") == 0


def test_its_table_is_checked_by_its_own_parameter_model(knife_kind, lens):
    with pytest.raises(InputError) as err:
        plan(lens, parse_mount(mount(**{"knife-vane": {"cuont": 3}})))
    assert err.value.field == "kinds.knife-vane.cuont" and "count" in err.value.valid
    with pytest.raises(InputError) as err:
        plan(lens, parse_mount(mount(**{"knife-vane": {"count": -1}})))
    assert err.value.field == "kinds.knife-vane.count"


def test_a_table_for_a_kind_nobody_registered_names_the_kinds_there_are(knife_kind, lens):
    with pytest.raises(InputError) as err:
        plan(lens, parse_mount(mount(**{"knife-vain": {"count": 3}})))
    assert err.value.field == "kinds.knife-vain" and "knife-vane" in err.value.detail
    assert "hood" in err.value.valid and "housing" in err.value.valid


@pytest.mark.slow
def test_init_search_builds_the_mount_with_the_new_kind_and_its_knife_edges_are_tagged(knife_kind, lens):
    """`init`'s strategy (cad.mount_search: plan, checks, solids, tessellation) takes a starting mount that
    asks for the new kind and hands it over as it is; the mesh tags each knife edge `vane-edge`."""
    from lensmount.cad.assembly import build_parts, tessellate
    from lensmount.cad.mount_search import find_mount

    start = mount(**{"knife-vane": {"count": 2}})
    found, tried = find_mount(lens, [start])
    assert found == start and tried == []
    spec = parse_mount(found)
    layout = plan(lens, spec)
    mesh, _ = tessellate(build_parts(layout, spec), spec, layout)
    edges = {t.part for t in mesh.tag_table if t.role == "vane-edge"}
    assert {"knife-vane-1", "knife-vane-2"} <= edges
