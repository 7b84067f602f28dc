"""Why hood vanes cannot change `lensmount check`'s verdict on the reference design, made precise.

`check` looks for walls both lit by the sun and seen by the detector. A line of sight from the
detector into object space must pass the diaphragm's land (the designed pupil), so in object
space it is a ray of the detector's field through the entrance pupil: inside the full-field beam
envelope that sets every vane's bore (envelope + margin) and clears the hood's wall. So the
detector sees no vane and no hood wall, wherever the vanes stand, and the lit walls `check`
reports are the same for every vane layout: on the reference at its exclusion angle (10°)
they are spacers inside the barrel, lit through the front group and seen through the rear
group (slow test: line-of-sight and even vanes of the same count, both meshes).

The vane construction hides lit hood walls from the *entrance aperture*: it matters for light
scattered a second time, by the first lens or inside the barrel, which this check does not
follow (benchmarks/bench_vane_layouts.py measures it with the Monte Carlo).

The fast test checks the first claim with the sequential real-ray trace (not the Embree tracer
`check` uses): object-space rays over the hood's mouth, at up to 1.6 × the field, clipped only
at the diaphragm's land, landing on the detector.
"""

import numpy as np
import pytest

from lensmount.optics.apertures import beam_envelope
from lensmount.optics.realrays import trace


def test_the_detector_sees_nothing_outside_the_beam_envelope_in_the_hood(reference_layout):
    layout, spec = reference_layout
    p = layout.prescription
    hood = layout.part("hood").template
    land = layout.part("diaphragm").template.inner_radius
    w, h = spec.housing.detector_width_mm, spec.housing.detector_height_mm
    # directions up to 1.6 × the field (a quadrant: the lens is a solid of revolution), origins over the mouth
    t = np.radians(np.linspace(0.0, 1.6 * p.max_field_deg, 13))
    tx, ty = (a.ravel() for a in np.meshgrid(t, t))
    d = np.column_stack([np.tan(tx), np.tan(ty), np.ones_like(tx)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    u = np.linspace(-1.0, 1.0, 25) * hood.inner_radius
    ox, oy = (a.ravel() for a in np.meshgrid(u, u))
    inside = np.hypot(ox, oy) <= hood.inner_radius
    z0 = hood.z_front - 1.0
    o = np.column_stack([ox[inside], oy[inside], np.full(inside.sum(), z0)])
    origins, dirs = np.repeat(o, len(d), axis=0), np.tile(d, (len(o), 1))
    rays = trace(p, origins, dirs, clip=False)
    stop = rays.points[p.stop_index]
    image = rays.points[-1]
    sees = (~rays.vignetted & (np.hypot(stop[:, 0], stop[:, 1]) <= land)
            & (np.abs(image[:, 0]) <= 0.5 * w) & (np.abs(image[:, 1]) <= 0.5 * h))
    assert sees.sum() > 1000  # the detector's lines of sight are well sampled
    # where those lines of sight run through the hood (straight in object space), against the envelope
    zs = np.linspace(hood.z_front, hood.z_back, 40)
    s = (zs[:, None] - z0) / dirs[sees, 2][None]
    r = np.hypot(origins[sees, 0][None] + s * dirs[sees, 0][None], origins[sees, 1][None] + s * dirs[sees, 1][None])
    beyond = r.max(axis=1) - beam_envelope(p, zs)
    assert beyond.max() < spec.vanes.aperture_margin_mm, \
        f"a line of sight from the detector passes {beyond.max():.3f} mm outside the envelope in the hood"
    assert (r.max(axis=1) < hood.inner_radius).all()


def _walls(report):
    """(part, face, area) of the lit walls seen; vanes by kind (their numbers shift with the count)."""
    return sorted((w.kind if w.kind == "vane" else w.part, w.face, round(w.area_mm2, 1)) for w in report.walls)


@pytest.mark.slow
def test_vane_layout_changes_what_the_aperture_sees_not_what_the_detector_sees(tmp_path, design_copier, reference):
    """The reference with line-of-sight vanes against even vanes of the same count (the
    construction's, 12) and its own 3 even vanes, the sun at the design's exclusion angle (10°) or
    beyond. Seen from the detector: the same lit walls (inside the barrel), no hood part among them.
    Seen from the entrance aperture: both even layouts leave some of the hood's bore lit and in
    sight (the 3 vanes tens of cm², the 12 the first bays, lit by suns steeper than ~70°), the
    line-of-sight vanes none of it."""
    from lensmount.loop.sightlines import lit_walls_seen
    from lensmount.cad.pipeline import regenerate
    from lensmount.cad.layout import plan
    from lensmount.mesh import TaggedMesh
    from lensmount.design.folder import load_design

    def placed(name, placement, count=None):
        folder = design_copier("double-gauss-360", tmp_path / name)
        text = (folder / "mount.toml").read_text().replace('placement = "even"', f'placement = "{placement}"')
        if count is not None:
            text = text.replace("count = 3 ", f"count = {count} ")
        if placement == "line-of-sight":
            text = text.replace("count = 3 ", "# count = 3 ")  # the construction's number, not a key's
        (folder / "mount.toml").write_text(text)
        regenerate(folder)
        return folder

    los = placed("los", "line-of-sight")
    design = load_design(los)
    meshes = {"line-of-sight": TaggedMesh.load(los / "build" / "mesh.npz")}
    count = sum(p.kind == "vane" and p.template.z_front < 0 for p in plan(design.prescription, design.mount).parts)
    meshes[f"even {count}"] = TaggedMesh.load(placed("even", "even", count) / "build" / "mesh.npz")
    meshes["even 3"] = TaggedMesh.load(reference[1] / "mesh.npz")
    angle = design.mount.exclusion_deg(design.prescription.max_field_deg)
    reports = {name: {view: lit_walls_seen(design.prescription, mesh, (44.5, 44.5), angle, view)
                      for view in ("detector", "aperture")} for name, mesh in meshes.items()}
    det = {name: _walls(r["detector"]) for name, r in reports.items()}
    print(f"seen from the detector at {angle:g}°: {det}")
    assert det["line-of-sight"] == det[f"even {count}"] == det["even 3"] and det["even 3"]
    assert not any(p == "hood" for p, _, _ in det["even 3"])

    def hood_bore(report):  # the hood's bore is its first face (templates.hood)
        return sum(w.area_mm2 for w in report.walls if w.part == "hood" and w.face == 0)

    bore = {name: hood_bore(r["aperture"]) for name, r in reports.items()}
    print(f"{count} line-of-sight vanes; lit hood bore seen from the entrance aperture: {bore} mm²")
    assert count == 12
    assert bore["even 3"] > 1000.0 and bore[f"even {count}"] > 0.0 and bore["line-of-sight"] == 0.0
