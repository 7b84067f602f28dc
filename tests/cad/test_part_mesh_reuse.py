"""A long-lived process (watch) tessellates again only the parts an edit changed, and the mesh it
assembles from the kept parts is the one a fresh tessellation gives."""

import numpy as np

from lensmount.cad import assembly
from lensmount.cad.assembly import build_assembly, tessellate
from lensmount.design.lens import load_lens
from lensmount.design.mount import load_mount


def test_an_edit_tessellates_only_the_parts_it_changed(examples_dir, monkeypatch):
    p = load_lens(examples_dir / "cooke-triplet" / "lens.toml")
    spec = load_mount(examples_dir / "cooke-triplet" / "mount.toml")
    longer = spec.model_copy(update={"hood": spec.hood.model_copy(update={"length_mm": spec.hood.length_mm + 5.0})})
    made = []
    real = assembly.tessellate_part
    monkeypatch.setattr(assembly, "tessellate_part", lambda *a, **k: made.append(a[1]) or real(*a, **k))
    monkeypatch.setattr(assembly, "_PART_MESHES", {})
    layout, parts = build_assembly(p, spec)
    tessellate(parts, spec, layout)
    assert sorted(made) == sorted(bp.name for bp in parts)
    made.clear()
    layout, parts = build_assembly(p, longer)
    kept, _ = tessellate(parts, longer, layout)
    unchanged = {bp.name for bp in parts} - set(made)
    assert made and len(made) < len(parts) and any("hood" in n for n in made), made
    assert unchanged  # parts away from the hood were kept, not tessellated again
    monkeypatch.setattr(assembly, "_PART_MESHES", {})
    fresh, _ = tessellate(parts, longer, layout)
    for a, b in ((kept.vertices, fresh.vertices), (kept.triangles, fresh.triangles), (kept.tags, fresh.tags)):
        assert np.array_equal(a, b)
    assert kept.tag_table == fresh.tag_table


def test_warm_writes_nothing_and_leaves_an_unchanged_regenerate_nothing_to_tessellate(examples_dir, tmp_path,
                                                                                       monkeypatch):
    """`watch` warms the CAD at start (the baseline's geometry came from the disk cache, which built no
    part): the regenerate of the same design then tessellates no part again."""
    import shutil

    from lensmount.cad.pipeline import regenerate, warm

    design = tmp_path / "cooke"
    shutil.copytree(examples_dir / "cooke-triplet", design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    before = sorted(p.name for p in design.iterdir())
    made = []
    real = assembly.tessellate_part
    monkeypatch.setattr(assembly, "tessellate_part", lambda *a, **k: made.append(a[1]) or real(*a, **k))
    monkeypatch.setattr(assembly, "_PART_MESHES", {})
    warm(design)
    assert made and sorted(p.name for p in design.iterdir()) == before  # built, nothing written
    made.clear()
    manifest = regenerate(design, tmp_path / "out", use_cache=False)
    assert made == [] and len(manifest.parts) > 0
