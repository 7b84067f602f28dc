"""`regenerate` on the reference design: STEP files, tagged mesh, manifest, cache."""

import json
import os
import shutil
import time

import numpy as np
import pytest
import trimesh

from lensmount.mesh import KINDS, ROLES

REQUIRED = ["barrel", "diaphragm", "hood", "housing", "retainer-1", "spacer-1", "spacer-2", "spacer-3",
            "spacer-4", "vane-1", "vane-2", "vane-3"] + [f"lens-{i}" for i in range(1, 7)]


def _import_step(path):
    import cadquery as cq

    return cq.importers.importStep(str(path))


def test_manifest_lists_every_part(reference):
    _, out, manifest = reference
    doc = json.loads((out / "manifest.json").read_text())
    assert doc["input_hash"] == manifest.input_hash and len(doc["input_hash"]) == 64
    names = [p["name"] for p in doc["parts"]]
    for n in REQUIRED:
        assert n in names
    for p in doc["parts"]:
        assert set(p) >= {"name", "kind", "finish", "step", "volume_mm3", "triangles"}
        assert p["kind"] in KINDS and p["volume_mm3"] > 0 and p["triangles"] > 0
        assert (out / p["step"]).is_file()
    assert (out / "assembly.step").is_file()


def test_step_reimports_with_the_manifest_volume(reference):
    _, out, manifest = reference
    for name in ("lens-1", "diaphragm", "spacer-2"):
        entry = manifest.part(name)
        shape = _import_step(out / entry.step).val()
        assert shape.isValid()
        assert shape.Volume() == pytest.approx(entry.volume_mm3, rel=1e-6)


def test_assembly_step_names_every_part(reference):
    _, out, manifest = reference
    text = (out / "assembly.step").read_text()
    for p in manifest.parts:
        assert f"PRODUCT('{p.name}'" in text
    assert "COLOUR_RGB" in text


@pytest.mark.slow
def test_every_step_reimports_as_a_valid_solid(reference):
    _, out, manifest = reference
    total = 0.0
    for p in manifest.parts:
        shape = _import_step(out / p.step).val()
        assert shape.isValid()
        assert shape.Volume() == pytest.approx(p.volume_mm3, rel=1e-6)
        total += p.volume_mm3
    solids = _import_step(out / "assembly.step").solids().vals()
    assert len(solids) == len(manifest.parts)
    assert sum(s.Volume() for s in solids) == pytest.approx(total, rel=1e-6)


def test_mesh_parts_are_closed_and_match_the_solids(reference, reference_mesh):
    _, _, manifest = reference
    m = reference_mesh
    assert np.isfinite(m.vertices).all()
    assert len(m.triangles) == sum(p.triangles for p in manifest.parts) < 300_000
    part_of = np.array([t.part for t in m.tag_table])[m.tags]
    for p in manifest.parts:
        sel = m.triangles[part_of == p.name]
        tm = trimesh.Trimesh(m.vertices, sel, process=True)
        assert tm.is_watertight, p.name
        assert tm.is_winding_consistent, p.name
        assert tm.volume > 0, p.name  # outward normals
        assert tm.volume == pytest.approx(p.volume_mm3, rel=0.02), p.name


def test_tags(reference, reference_mesh):
    design, _, manifest = reference
    from lensmount.design.lens import load_lens
    from lensmount.optics.profiles import Profile

    p = load_lens(design / "lens.toml")
    m = reference_mesh
    finish = {e.name: e.finish for e in manifest.parts}
    optical = {}
    for t in m.tag_table:
        assert t.role in ROLES and t.kind in KINDS
        assert t.finish == finish[t.part]
        if t.role == "optical":
            optical.setdefault(t.part, set()).add(t.surface)
    assert optical == {"lens-1": {0, 1}, "lens-2": {2, 3}, "lens-3": {3, 4}, "lens-4": {6, 7},
                       "lens-5": {7, 8}, "lens-6": {9, 10}}
    roles = {(t.part, t.role) for t in m.tag_table}
    assert ("diaphragm", "diaphragm-edge") in roles
    assert all((f"vane-{i}", "vane-edge") in roles for i in (1, 2, 3))
    assert ("lens-1", "lens-edge") in roles and ("lens-1", "bevel") in roles
    # every optical vertex lies on its analytic surface
    zv = p.vertex_z
    for k, t in enumerate(m.tag_table):
        if t.role != "optical":
            continue
        v = m.vertices[np.unique(m.triangles[m.tags == k])]
        r2 = v[:, 0] ** 2 + v[:, 1] ** 2
        np.testing.assert_allclose(v[:, 2], zv[t.surface] + Profile.of(p.surfaces[t.surface]).sag(r2), atol=1e-6)
        # the optical face covers the clear aperture (the tracer refines hits there)
        assert np.sqrt(r2).max() >= p.surfaces[t.surface].clear_semi_diameter


def test_diaphragm_edge_is_the_50_um_land(reference, reference_mesh):
    m = reference_mesh
    k = [i for i, t in enumerate(m.tag_table) if t.role == "diaphragm-edge"]
    v = m.vertices[np.unique(m.triangles[np.isin(m.tags, k)])]
    assert v[:, 2].max() - v[:, 2].min() == pytest.approx(0.05, abs=1e-9)


def test_second_run_comes_from_the_cache(reference, monkeypatch):
    from lensmount.cad import pipeline

    design, out, manifest = reference
    before = {p.name: os.stat(out / p.step).st_mtime_ns for p in manifest.parts}

    def boom(*a, **k):
        raise AssertionError("the CAD kernel ran on unchanged inputs")

    monkeypatch.setattr(pipeline, "build_assembly", boom)
    again = pipeline.regenerate(design, out)
    assert again.cached and again.input_hash == manifest.input_hash
    assert {p.name: os.stat(out / p.step).st_mtime_ns for p in again.parts} == before


def test_changing_vane_count_rewrites_only_vane_steps(reference, tmp_path):
    from lensmount.cad.pipeline import regenerate

    design, out, manifest = reference
    d2, o2 = tmp_path / "design", tmp_path / "out"
    shutil.copytree(design, d2)
    shutil.copytree(out, o2)
    old_bytes = {p.name: (o2 / p.step).read_bytes() for p in manifest.parts}
    old_mtime = {p.name: os.stat(o2 / p.step).st_mtime_ns for p in manifest.parts}
    old_drawing = {p.name: os.stat(o2 / p.dxf).st_mtime_ns for p in manifest.parts}
    text = (d2 / "mount.toml").read_text().replace("count = 3 ", "count = 4 ")
    assert "count = 4" in text
    (d2 / "mount.toml").write_text(text)
    time.sleep(0.01)
    new = regenerate(d2, o2)
    assert not new.cached and new.input_hash != manifest.input_hash
    changed = set()
    for p in new.parts:
        if p.name not in old_bytes or (o2 / p.step).read_bytes() != old_bytes[p.name]:
            changed.add(p.name)
        elif os.stat(o2 / p.step).st_mtime_ns != old_mtime[p.name]:
            changed.add(p.name + " (rewritten)")
    assert changed and all(n.startswith("vane-") for n in changed), changed
    redrawn = {p.name for p in new.parts if os.stat(o2 / p.dxf).st_mtime_ns != old_drawing.get(p.name)}
    assert redrawn and all(n.startswith("vane-") for n in redrawn), redrawn  # drawings cached like STEP
    assert sum(p.kind == "vane" for p in new.parts) == sum(p.kind == "vane" for p in manifest.parts) + 1
    # and back: the earlier outputs come from the content-addressed cache
    (d2 / "mount.toml").write_text(text.replace("count = 4 ", "count = 3 "))
    back = regenerate(d2, o2)
    assert back.cached and back.input_hash == manifest.input_hash
    assert [p.name for p in back.parts if (o2 / p.step).read_bytes() != old_bytes[p.name]] == []
    assert not (o2 / "parts" / f"vane-{len([p for p in new.parts if p.kind == 'vane'])}.step").exists()


def test_bill_of_materials_beside_the_step_files(reference):
    """bom.csv lists every part with its material and mass; the diaphragm plate's volume matches
    the annulus minus its bevel computed by hand (Pappus), its mass aluminium's 2.70 g/cm³."""
    import csv
    import math

    design, out, manifest = reference
    rows = {r["part"]: r for r in csv.DictReader((out / "bom.csv").open())}
    assert set(rows) == {p.name for p in manifest.parts}
    assert rows["lens-1"]["material"] == "N-SSK2" and rows["barrel"]["material"] == "aluminium 6061-T6"
    assert "N-BK7 assumed" in rows["lens-1"]["note"]
    d = rows["diaphragm"]
    r0, R, t, land = 16.299, 30.9812, 1.0, 0.05  # examples/double-gauss-360: land radius, outside, plate
    run = t - land  # 45° bevel
    bevel = 0.5 * run * run * 2 * math.pi * (r0 + run / 3)  # triangle (r0, land)-(r0+run, t) revolved
    expected = math.pi * (R ** 2 - r0 ** 2) * t - bevel
    assert float(d["volume_mm3"]) == pytest.approx(expected, rel=2e-3)
    assert float(d["mass_g"]) == pytest.approx(expected * 2.70e-3, rel=2e-3)
