"""A stop in front of the first element (a front aperture) or behind the last one (a rear stop):
the diaphragm is clamped between a barrel lip and a spacer, its land passes the designed pupil,
and every other bore clears the full-field beam (the layout's checks). The slow test builds both
into STEP and measures the realised pupil on the mesh."""

from pathlib import Path

import pytest

from lensmount.cad.checks import penetration
from lensmount.templates.profile import outline
from lensmount.cad.layout import plan
from lensmount.design.lens import load_lens
from lensmount.design.mount import parse_mount

MOUNT = {"name": "two singlets", "hood": {"length_mm": 10.0}, "housing": {"detector_width_mm": 3.0, "detector_height_mm": 3.0}}


def two_singlets(folder: Path, stop: str) -> Path:
    """Two f = 60 mm N-BK7 singlets, EPD 10 mm, ±3°; the stop 5 mm in front ("front") or behind ("rear")."""
    lines = ['name = "two singlets"', "aperture = { entrance_pupil_diameter = 10.0 }",
             "[wavelengths]", "values_um = [0.5875618]", "weights = [1.0]", "primary = 1",
             "[field]", "angles_deg = [0.0, 2.0, 3.0]"]
    surfaces = [(60.0, 4.0, "N-BK7"), (-60.0, 6.0, "AIR"), (60.0, 4.0, "N-BK7")]
    surfaces = ([('"inf"', 5.0, "AIR")] + surfaces + [(-60.0, 28.0, "AIR")] if stop == "front"
                else surfaces + [(-60.0, 5.0, "AIR"), ('"inf"', 23.0, "AIR")])
    stop_index = 0 if stop == "front" else len(surfaces) - 1
    for i, (r, t, m) in enumerate(surfaces):
        lines += ["[[surface]]", f"radius = {r}", f"thickness = {t}", f'material = "{m}"']
        lines += ["stop = true"] if i == stop_index else []
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "lens.toml").write_text("\n".join(lines) + "\n")
    (folder / "mount.toml").write_text(
        'name = "two singlets"\n[hood]\nlength_mm = 10.0\n'
        "[housing]\ndetector_width_mm = 3.0\ndetector_height_mm = 3.0\n")
    return folder


@pytest.mark.parametrize("stop", ["front", "rear"])
def test_outer_stop_is_clamped_by_a_lip_and_a_spacer(tmp_path, stop):
    from lensmount.cad.seats import pupil_edge_radius

    d = two_singlets(tmp_path / stop, stop)
    p = load_lens(d / "lens.toml")
    layout = plan(p, parse_mount(MOUNT))
    dia = layout.part("diaphragm").template
    assert dia.z_stop == pytest.approx(p.vertex_z[p.stop_index])
    assert dia.inner_radius == pytest.approx(pupil_edge_radius(p, dia.z_stop - 0.025, dia.z_stop + 0.025))
    z0, z1 = dia.z_range()
    bore = layout.part("barrel").template.bore
    lip = [z for r, z in bore if r < dia.outer_radius]
    # the barrel lip touches the diaphragm on the side away from the lens, a spacer on the other
    if stop == "front":
        assert min(z for _, z in bore) < z0 and any(abs(z - z0) < 1e-9 for z in lip)
        spacer = layout.part("spacer-1").template
        assert spacer.front_z == pytest.approx(z1)
    else:
        assert max(z for _, z in bore) > z1 and any(abs(z - z1) < 1e-9 for z in lip)
        spacer = [pp.template for pp in layout.parts if pp.kind == "spacer"][-1]
        assert spacer.back_z == pytest.approx(z0)
    # touching, never cutting
    segs = {pp.name: pp.template.segments() for pp in layout.parts}
    assert penetration(outline(segs["diaphragm"]), outline(segs["barrel"])) < 2e-3


@pytest.mark.slow
@pytest.mark.parametrize("stop", ["front", "rear"])
def test_outer_stop_regenerates_and_realises_the_pupil(tmp_path, stop):
    from lensmount.cad.pipeline import regenerate
    from lensmount.mesh import TaggedMesh
    from lensmount.cad.pupil import realised_entrance_pupil
    from lensmount.optics.paraxial import paraxial

    d = two_singlets(tmp_path / stop, stop)
    manifest = regenerate(d, tmp_path / "out")  # runs the beam and interference checks
    assert "diaphragm" in {p.name for p in manifest.parts}
    p = load_lens(d / "lens.toml")
    pupil = realised_entrance_pupil(p, TaggedMesh.load(tmp_path / "out" / "mesh.npz"))
    assert abs(pupil.diameter / paraxial(p).epd - 1) < 5e-3
    assert set(pupil.limited_by) == {"diaphragm"}
