"""Every seat style builds a valid, checked, watertight mount (Cooke triplet fast, reference slow)."""

import pytest

from lensmount.cad.assembly import build_assembly, tessellate
from lensmount.design.lens import load_lens
from lensmount.design.mount import load_mount
from lensmount.errors import GeometryError

VARIANTS = [{"contact": "tangent"}, {"default": "shoulder"}, {"front": "shoulder", "rear": "retainer"}]


def _build(examples_dir, example, seats):
    p = load_lens(examples_dir / example / "lens.toml")
    base = load_mount(examples_dir / example / "mount.toml")
    spec = base.model_copy(update={"seats": base.seats.model_copy(update=seats)})
    layout, parts = build_assembly(p, spec)
    mesh, counts = tessellate(parts, spec, layout)  # raises if a part is not watertight
    return layout, parts, mesh


@pytest.mark.parametrize("seats", VARIANTS, ids=lambda s: "-".join(f"{k}={v}" for k, v in s.items()))
def test_cooke_variants(examples_dir, seats):
    layout, parts, mesh = _build(examples_dir, "cooke-triplet", seats)
    kinds = {bp.plan.kind for bp in parts}
    assert {"lens", "barrel", "diaphragm", "hood", "housing"} <= kinds
    if seats.get("default") == "shoulder":
        assert sum(bp.plan.kind == "spacer" for bp in parts) == 1  # only the one at the diaphragm
    if seats.get("rear") == "retainer":
        assert sum(bp.plan.kind == "retainer" for bp in parts) == 1


@pytest.mark.slow
@pytest.mark.parametrize("seats", VARIANTS + [{"element": {4: "shoulder"}}])
def test_reference_variants(examples_dir, seats):
    _build(examples_dir, "double-gauss-360", seats)


def test_seat_for_a_cemented_element_is_refused(examples_dir):
    with pytest.raises(GeometryError) as exc:
        _build(examples_dir, "double-gauss-360", {"element": {3: "shoulder"}})
    assert exc.value.field == "seats.element.3"
