"""The mount leaves the beam alone: real rays of the full field, traced through the lens,
never meet a spacer, vane, retainer, barrel, hood or housing triangle; rays aimed just
outside the stop radius are stopped by the diaphragm (it is the aperture stop)."""

import numpy as np
import pytest
import trimesh

from lensmount.optics.realrays import aim, trace

AZIMUTHS_DEG = (0.0, 37.0, 101.0, 223.0)  # the mesh is faceted: look at several angles


def _rays(p, radius_scale):
    """Polylines (K+1, N, 3) of real rays: fields 0..max, a pupil rim at radius_scale, 3 colours."""
    fields = np.unique(np.concatenate([np.linspace(0.0, p.max_field_deg, 6), p.field_angles_deg]))
    phi = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)
    pupil = np.concatenate([radius_scale * np.column_stack([np.cos(phi), np.sin(phi)]),
                            0.5 * np.column_stack([np.cos(phi[::4]), np.sin(phi[::4])]), [[0.0, 0.0]]])
    polylines = []
    for wl in p.wavelengths_um:
        o, d = aim(p, fields, pupil, wl)
        r = trace(p, o, d, wl, clip=False)
        assert not r.vignetted.any()
        start = o - 260.0 * d  # from in front of the hood
        polylines.append(np.concatenate([start[None], r.points], axis=0))
    return np.concatenate(polylines, axis=1)


def _rotate(pts, deg):
    a = np.radians(deg)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    return pts @ rot.T


def _first_hits(mesh, polylines):
    """For every segment of every ray: (segment k, ray n, triangle) of hits inside the segment."""
    hits = []
    for k in range(len(polylines) - 1):
        a, b = polylines[k], polylines[k + 1]
        seg = b - a
        length = np.linalg.norm(seg, axis=1)
        ok = length > 1e-9
        d = seg[ok] / length[ok, None]
        tri, ray, loc = mesh.ray.intersects_id(a[ok], d, multiple_hits=False, return_locations=True)
        dist = np.einsum("ij,ij->i", loc - a[ok][ray], d[ray])
        inside = (dist > 1e-6) & (dist < length[ok][ray] - 1e-6)
        idx = np.flatnonzero(ok)[ray[inside]]
        hits += [(k, int(n), int(t)) for n, t in zip(idx, tri[inside])]
    return hits


@pytest.fixture(scope="module")
def mechanical(reference_mesh):
    m = reference_mesh
    part_of = np.array([t.part for t in m.tag_table])[m.tags]
    keep = ~np.char.startswith(part_of.astype(str), "lens-")
    tm = trimesh.Trimesh(m.vertices, m.triangles[keep], process=False)
    return tm, part_of[keep]


def test_no_mount_part_enters_the_full_field_beam(reference, mechanical):
    from lensmount.design.lens import load_lens

    design, _, _ = reference
    p = load_lens(design / "lens.toml")
    tm, part_of = mechanical
    base = _rays(p, 0.995)
    for az in AZIMUTHS_DEG:
        hits = _first_hits(tm, _rotate(base, az))
        assert not hits, f"azimuth {az}: {len(hits)} ray segments hit {sorted({part_of[t] for _, _, t in hits})}"


def test_the_diaphragm_is_the_aperture_stop(reference, mechanical):
    from lensmount.design.lens import load_lens

    design, _, _ = reference
    p = load_lens(design / "lens.toml")
    tm, part_of = mechanical
    rays = _rays(p, 1.01)
    rim = np.zeros(rays.shape[1], bool)
    n_per_wl = rays.shape[1] // len(p.wavelengths_um)
    n_pupil = 48 + 12 + 1
    for w in range(len(p.wavelengths_um)):
        for f in range(n_per_wl // n_pupil):
            rim[w * n_per_wl + f * n_pupil: w * n_per_wl + f * n_pupil + 48] = True
    hits = _first_hits(tm, rays)
    first = {}
    for k, n, t in sorted(hits):
        first.setdefault(n, part_of[t])
    blocked = np.array([n in first for n in range(rays.shape[1])])
    by_diaphragm = np.array([first.get(n) == "diaphragm" for n in range(rays.shape[1])])
    # rays 1 % outside the stop radius may graze a front part first (they are outside the
    # clear aperture there too); none may reach the detector, and the diaphragm stops most
    assert blocked[rim].all(), f"{(~blocked[rim]).sum()} rays at 1.01 x stop radius reach the detector"
    assert by_diaphragm[rim].mean() > 0.9
    assert not blocked[~rim].any(), "a ray inside the pupil was blocked"
