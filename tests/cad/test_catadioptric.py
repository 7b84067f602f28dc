"""Lenses with mirrors through the whole chain: `init --lens` → regenerate → beam clear → tracer
agrees with the sequential trace in the built mount → case-2 simulation (tests/optics/corpus).

Beam clear, for a folded path: real rays of the full field (every wavelength, the pupil filled
evenly by area) are followed along their sequential polylines through the assembled mesh. A ray
stopped on its way to the first mirror by a central part (one that does not reach the barrel's
bore: the secondary, its cell) or by a spider vane is obscured by design, as Zemax's central
obscuration is; every other ray must meet no face but the optical faces it is traced through.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from tests.cad.step_checks import assert_case2_simulates, assert_step_parts_valid

ROOT = Path(__file__).resolve().parents[2]
CORPUS = ROOT / "tests" / "optics" / "corpus"
def _text(path: Path) -> str:
    raw = path.read_bytes()
    return raw.decode("utf-16") if raw[:2] in (b"\xff\xfe", b"\xfe\xff") else raw.decode("latin-1")


MIRRORS = sorted(p for p in CORPUS.glob("*.zmx") if "GLAS MIRROR" in _text(p))


def _twins(p) -> list[int]:
    """Each surface's first earlier surface with the same vertex and shape (a return pass), else itself."""
    zs, out = p.vertex_z, []
    for i, s in enumerate(p.surfaces):
        out.append(next((j for j in range(i) if abs(zs[j] - zs[i]) < 1e-9 and not s.mirror
                         and (p.surfaces[j].radius, p.surfaces[j].conic) == (s.radius, s.conic)), i))
    return out


def _rays(p, n_rings=7, n_spokes=24):
    """Polylines (S+2, N, 3) of the full field's real rays, from 30 mm in front of everything, the
    field index and the wavelength index of each ray; rays the file's own apertures stop are left out."""
    from lensmount.optics.realrays import aim, trace

    rho = np.sqrt((np.arange(n_rings) + 0.5) / n_rings)          # equal-area rings
    phi = np.linspace(0.0, 2 * np.pi, n_spokes, endpoint=False)
    pupil = np.column_stack([np.outer(rho, np.cos(phi)).ravel(), np.outer(rho, np.sin(phi)).ravel()])
    fields = np.array(sorted({0.0, 0.5 * p.max_field_deg, p.max_field_deg}))
    z0 = min(p.vertex_z) - 30.0
    lines, field_of, colour = [], [], []
    for w, wl in enumerate(p.wavelengths_um):
        o, d = aim(p, fields, pupil, wl)
        r = trace(p, o, d, wl)
        ok = ~r.vignetted
        s = (z0 - o[:, 2]) / d[:, 2]
        lines.append(np.concatenate([(o + s[:, None] * d)[None], r.points], axis=0)[:, ok])
        field_of.append(np.repeat(np.arange(len(fields)), len(pupil))[ok])
        colour.append(np.full(ok.sum(), w))
    return np.concatenate(lines, axis=1), np.concatenate(field_of), np.concatenate(colour), len(fields)


def _blocks(p, mesh, lines):
    """Per ray: (segment, part) of the first face met strictly inside a segment that is not an optical
    face of the segment's own end surfaces; None for a ray that passes."""
    import trimesh

    twin = _twins(p)
    tm = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False)
    tags = [mesh.tag_table[t] for t in mesh.tags]
    n = lines.shape[1]
    first = [None] * n
    for k in range(len(lines) - 1):
        ends = {twin[k - 1] if k > 0 else -1, twin[k] if k < len(p.surfaces) else -2}
        a, b = lines[k], lines[k + 1]
        length = np.linalg.norm(b - a, axis=1)
        live = np.flatnonzero((length > 1e-9) & np.array([f is None for f in first]))
        if not live.size:
            continue
        dirs = (b - a)[live] / length[live, None]
        tri, ray, loc = tm.ray.intersects_id(a[live], dirs, multiple_hits=True, return_locations=True)
        dist = np.einsum("ij,ij->i", loc - a[live][ray], dirs[ray])
        order = np.argsort(dist)
        for t, r_, s in zip(tri[order], ray[order], dist[order]):
            i = live[r_]
            if first[i] is not None or not (1e-6 < s < length[i] - 1e-6):
                continue
            tag = tags[t]
            if tag.role == "optical" and twin[tag.surface] in ends:
                continue
            first[i] = (k, tag.part)
    return first


def _spiders(mesh, bore: float) -> set[str]:
    """Parts that reach the barrel's bore at a few azimuths only: vanes, not rings."""
    out = set()
    for part in {t.part for t in mesh.tag_table} - {"barrel"}:
        k = [i for i, t in enumerate(mesh.tag_table) if t.part == part]
        v = mesh.vertices[np.unique(mesh.triangles[np.isin(mesh.tags, k)])]
        far = v[np.hypot(v[:, 0], v[:, 1]) > 0.9 * bore]
        if len(far):
            az = np.sort(np.degrees(np.arctan2(far[:, 1], far[:, 0])))
            if np.max(np.diff(np.concatenate([az, az[:1] + 360.0]))) > 30.0:
                out.add(part)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("lens", MIRRORS, ids=[p.stem for p in MIRRORS])
def test_mirror_lens_gets_a_mount_that_builds_clears_the_beam_traces_like_the_file_and_simulates(lens, tmp_path):
    from lensmount.mesh import TaggedMesh
    from lensmount.design.folder import load_design
    from lensmount.design.scene import scene_from_dict
    from lensmount.scene.build import build_scene
    from lensmount.physics.rays import RayBatch
    from lensmount.trace.tracer import DETECTOR, Tracer

    design = tmp_path / "design"
    result = CliRunner().invoke(app, ["init", str(design), "--lens", str(lens)])
    assert result.exit_code == 0 and "does not build" not in (design / "mount.toml").read_text(), result.output
    reg = CliRunner().invoke(app, ["regenerate", str(design), "--quiet"])
    assert reg.exit_code == 0, reg.output

    # valid STEP: every part re-imports as one valid solid of the recorded volume
    build = design / "build"
    assert_step_parts_valid(build)

    # beam clear past the central obscuration
    d = load_design(design)
    p, mesh = d.prescription, TaggedMesh.load(build / "mesh.npz")
    in_barrel = np.isin(mesh.tags, [k for k, t in enumerate(mesh.tag_table) if t.part == "barrel"])
    barrel = mesh.vertices[np.unique(mesh.triangles[in_barrel])]
    bore = float(np.hypot(barrel[:, 0], barrel[:, 1]).min())
    reach = {t.part: 0.0 for t in mesh.tag_table}
    for k, t in enumerate(mesh.tag_table):
        v = mesh.vertices[np.unique(mesh.triangles[mesh.tags == k])]
        reach[t.part] = max(reach[t.part], float(np.hypot(v[:, 0], v[:, 1]).max()))
    central = {name for name, r in reach.items() if r < bore - 0.1} | (spiders := _spiders(mesh, bore))
    lines, field_of, colour, n_fields = _rays(p)
    first_mirror = next(i for i, s in enumerate(p.surfaces) if s.mirror)
    blocks = _blocks(p, mesh, lines)
    obscured = np.array([b is not None and b[1] in central and (b[0] <= first_mirror or b[1] in spiders)
                         for b in blocks])
    clashes = sorted({(b[0], b[1]) for b, o in zip(blocks, obscured) if b is not None and not o})
    assert clashes == [], f"segments and parts met by unobscured rays: {clashes}"
    for f in range(n_fields):   # the obscuration is central: most of every field's light gets through
        assert obscured[field_of == f].mean() < 0.6

    # the non-sequential tracer in the built mount lands every unobscured on-axis ray where the file does
    det = {"width_mm": 4.0, "height_mm": 4.0, "pixels": [4, 4]}
    scene = build_scene(p, mesh, scene_from_dict({
        "source": {"type": "collimated", "off_axis_deg": 0.0, "azimuth_deg": 90.0}, "detector": det,
        "effects": {"scatter": False, "ghosts": False, "direct": True, "absorption": False},  # R of the mirrors alone
        "assign": {"*": "absorber"}}))
    on_axis = np.flatnonzero((field_of == 0) & ~obscured)
    start = lines[0, on_axis]
    ev = Tracer(scene).next_event(RayBatch.make(start, lines[1, on_axis] - start, wavelength=colour[on_axis]))
    arrived = ev.kind == DETECTOR
    assert arrived.mean() > 0.98, f"{(~arrived).sum()} of {arrived.size} unobscured on-axis rays did not arrive"
    np.testing.assert_allclose(ev.position[arrived], lines[-1, on_axis][arrived], atol=1e-6)
    np.testing.assert_allclose(ev.weight[arrived], 0.90 ** sum(s.mirror for s in p.surfaces), rtol=1e-9)

    # the paper's case 2 simulates without error, every number finite
    assert_case2_simulates(design, tmp_path / "run", 3000)
    scene_file = design / "scenes" / "case2-lambertian.toml"
    assert tomllib.loads(scene_file.read_text())["source"]["off_axis_deg"] == pytest.approx(p.max_field_deg + 5.0,
                                                                                            abs=0.01)



def test_cassegrain_plan_holds_the_secondary_on_a_spider_and_opens_the_primary_for_the_returning_light():
    """HoO-V2C18Ex03 planned without CAD: against the file's own rays, traced here."""
    from lensmount.cad.checks import check_layout
    from lensmount.cad.layout import plan
    from lensmount.design.lens import load_lens
    from lensmount.cad.starter import starter_mount
    from lensmount.design.mount import parse_mount
    from lensmount.optics.realrays import aim, trace
    from lensmount.templates.cell import SpiderCell
    from lensmount.templates.mirror import MirrorElement

    p = load_lens(CORPUS / "HoO-V2C18Ex03.zmx")
    mount, problem = starter_mount(p, "cassegrain")
    assert problem is None
    spec = parse_mount(mount)
    layout = plan(p, spec)
    check_layout(layout, spec, {q.name: q.template.segments() for q in layout.parts})
    parts = {q.name: q for q in layout.parts}
    assert {q.kind for q in layout.parts} == {"barrel", "mirror", "cell"}
    secondary, primary = parts["mirror-1"].template, parts["mirror-2"].template   # numbered along z
    assert isinstance(secondary, MirrorElement) and secondary.back.index == 2 and primary.front.index == 1
    # the coated zones end at the file's clear semi-diameters: the primary's is the stop
    coated = {s.surface: max(r for r, _ in s.points) for q in (primary, secondary) for s in q.segments()
              if s.role == "optical"}
    assert coated == {1: pytest.approx(p.surfaces[1].clear_semi_diameter),
                      2: pytest.approx(p.surfaces[2].clear_semi_diameter)}
    # the secondary's cell stands on vanes that reach the barrel's bore
    spider = parts["cell-1"].template
    bore = parts["barrel"].template.bore[0][0]
    assert isinstance(spider, SpiderCell) and spider.reach == pytest.approx(bore)
    assert all(r_out <= bore for _, r_out, _ in spider.vane_boxes())
    # the primary's hole passes the light from the secondary to the image (every field, colour, the pupil rim)
    phi = np.linspace(0, 2 * np.pi, 36, endpoint=False)
    z0, z1 = float(primary.front_z(primary.hole_radius)), primary.back_z_flat
    widest = 0.0
    for wl in p.wavelengths_um:
        o, d = aim(p, [0.0, p.max_field_deg], np.column_stack([np.cos(phi), np.sin(phi)]), wl)
        r = trace(p, o, d, wl)
        ok = ~r.vignetted                        # the file's secondary clips a few rim rays of the 1° field
        assert ok.mean() > 0.9
        a, b = r.points[2][ok], r.points[3][ok]  # secondary -> image plane
        for z in np.linspace(z0, z1, 20):
            t = (z - a[:, 2]) / (b[:, 2] - a[:, 2])
            widest = max(widest, float(np.hypot(*(a + t[:, None] * (b - a))[:, :2].T).max()))
    assert widest < primary.hole_radius < p.surfaces[1].clear_semi_diameter
