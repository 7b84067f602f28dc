"""Small tagged meshes built with numpy: scene objects (disk, rectangle) and test geometry
(lens elements revolved from their prescription, boxes, spheres, tubes).

Every builder returns a `TaggedMesh` in the assembly frame (mm). Solids are closed, with
triangles counter-clockwise seen from outside. Placement of a scene object: its centre
(x, y, z) and a tilt: rotation by `tilt_x_deg` about x, then `tilt_y_deg` about y, applied
to an object whose normal is +z.
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.optics.prescription import Prescription
from lensmount.optics.profiles import Profile


def rotation(tilt_x_deg: float, tilt_y_deg: float) -> np.ndarray:
    """(3, 3) rotation: about x by tilt_x, then about y by tilt_y."""
    a, b = math.radians(tilt_x_deg), math.radians(tilt_y_deg)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    return ry @ rx


def _single(vertices, triangles, tag: FaceTag) -> TaggedMesh:
    return TaggedMesh(np.asarray(vertices, float), np.asarray(triangles, np.int64),
                      np.zeros(len(triangles), np.int32), [tag])


def disk(centre, radius: float, *, tilt_x_deg: float = 0.0, tilt_y_deg: float = 0.0, part: str = "object",
         finish: str = "absorber", segments: int = 64) -> TaggedMesh:
    """A zero-thickness disc (both sides scatter alike), normal +z before tilting."""
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    v = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.zeros(segments)])
    v = np.vstack([[0.0, 0.0, 0.0], v])
    i = np.arange(segments)
    tris = np.column_stack([np.zeros(segments, int), 1 + i, 1 + (i + 1) % segments])
    v = v @ rotation(tilt_x_deg, tilt_y_deg).T + np.asarray(centre, float)
    return _single(v, tris, FaceTag(part, "object", "object", finish))


def rectangle(centre, width: float, height: float, *, tilt_x_deg: float = 0.0, tilt_y_deg: float = 0.0,
              part: str = "object", finish: str = "absorber") -> TaggedMesh:
    """A zero-thickness rectangle width (x) × height (y), normal +z before tilting."""
    w, h = 0.5 * width, 0.5 * height
    v = np.array([[-w, -h, 0], [w, -h, 0], [w, h, 0], [-w, h, 0]], float)
    v = v @ rotation(tilt_x_deg, tilt_y_deg).T + np.asarray(centre, float)
    return _single(v, [[0, 1, 2], [0, 2, 3]], FaceTag(part, "object", "object", finish))


def box(lo, hi, *, part: str = "box", kind: str = "housing", role: str = "mount", finish: str = "absorber",
        inward: bool = False) -> TaggedMesh:
    """A closed axis-aligned box; `inward` flips the triangles (an enclosure seen from inside)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = np.array([t for a, b, cc, d in quads for t in ((a, b, cc), (a, cc, d))])
    if inward:
        tris = tris[:, ::-1]
    return _single(c, tris, FaceTag(part, kind, role, finish))


def sphere(centre, radius: float, *, subdivisions: int = 3, part: str = "sphere", finish: str = "absorber",
           kind: str = "housing", role: str = "mount") -> TaggedMesh:
    """A closed icosphere (trimesh), vertices on the sphere."""
    import trimesh  # lazy: trimesh takes ~1 s to load; only the sphere needs it

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return _single(np.asarray(m.vertices) + np.asarray(centre, float), m.faces, FaceTag(part, kind, role, finish))


def tube(z0: float, z1: float, r_inner: float, r_outer: float, *, part: str = "barrel", kind: str = "barrel",
         finish: str = "black-anodised", segments: int = 128) -> TaggedMesh:
    """A closed annular tube (a barrel) between z0 and z1, role 'mount'."""
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    rings = [(r_inner, z0), (r_outer, z0), (r_outer, z1), (r_inner, z1)]
    v = np.vstack([np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(segments, z)]) for r, z in rings])
    tris = []
    i = np.arange(segments)
    j = (i + 1) % segments
    for a in range(4):  # the ring profile is a closed loop: inner@z0 -> outer@z0 -> outer@z1 -> inner@z1
        b = (a + 1) % 4
        ia, ja, ib, jb = a * segments + i, a * segments + j, b * segments + i, b * segments + j
        tris.append(np.column_stack([ia, ib, jb]))
        tris.append(np.column_stack([ia, jb, ja]))
    tris = np.vstack(tris)
    return _fix_orientation(_single(v, tris, FaceTag(part, kind, "mount", finish)))


def _fix_orientation(mesh: TaggedMesh) -> TaggedMesh:
    """Flip all triangles if the signed volume is negative (so normals point outward)."""
    v, t = mesh.vertices, mesh.triangles
    vol = np.einsum("ij,ij->i", v[t[:, 0]], np.cross(v[t[:, 1]], v[t[:, 2]])).sum()
    if vol < 0:
        mesh = TaggedMesh(v, t[:, ::-1].copy(), mesh.tags, mesh.tag_table)
    return mesh


def _cap(profile: Profile, z_vertex: float, radius: float, rings: int, segments: int):
    """Polar grid on a surface: vertices (1 + rings·segments, 3) and triangles, centre first."""
    rr = radius * np.sqrt(np.linspace(0.0, 1.0, rings + 1)[1:])  # equal-area rings
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    r = np.repeat(rr, segments)
    p = np.tile(phi, rings)
    # A hemisphere's rim sits exactly at the conic's edge: keep r² on the defined side of it.
    r2max = profile.max_radius() ** 2
    z = z_vertex + profile.sag(np.minimum(r * r, r2max * (1.0 - 1e-15)))
    v = np.vstack([[0.0, 0.0, z_vertex], np.column_stack([r * np.cos(p), r * np.sin(p), z])])
    i = np.arange(segments)
    j = (i + 1) % segments
    tris = [np.column_stack([np.zeros(segments, int), 1 + i, 1 + j])]
    for k in range(rings - 1):
        a, b = 1 + k * segments, 1 + (k + 1) * segments
        tris.append(np.column_stack([a + i, b + i, b + j]))
        tris.append(np.column_stack([a + i, b + j, a + j]))
    return v, np.vstack(tris)


def lens_element(prescription: Prescription, first: int, last: int, semi_diameter: float, *, part: str,
                 rings: int = 24, segments: int = 96, finish: str = "ground-glass") -> TaggedMesh:
    """A closed glass solid bounded by optical surfaces first..last (0-based) and a cylindrical rim.

    Cemented interfaces inside (first < i < last) are included as internal optical faces, so the
    tracer sees each surface once per crossing. Optical triangles carry `surface = i`; the rim is
    tagged `lens-edge`. Outer faces wind counter-clockwise seen from outside (the TaggedMesh rule).
    """
    zs = prescription.vertex_z
    meshes = []
    rims = []
    for i in range(first, last + 1):
        prof = Profile.of(prescription.surfaces[i])
        v, t = _cap(prof, zs[i], semi_diameter, rings, segments)
        if i == first:  # caps face +z; the front one must face the object side to point out of the glass
            t = t[:, ::-1]
        meshes.append(TaggedMesh(v, t, np.zeros(len(t), np.int32),
                                 [FaceTag(part, "lens", "optical", "polished", surface=i, face=i - first)]))
        rims.append(v[1 + (rings - 1) * segments:])
    # Rim: a cylinder joining the outer rings of the first and last surfaces.
    a, b = rims[0], rims[-1]
    i = np.arange(segments)
    j = (i + 1) % segments
    v = np.vstack([a, b])
    t = np.vstack([np.column_stack([i, segments + j, segments + i]), np.column_stack([i, j, segments + j])])
    meshes.append(TaggedMesh(v, t, np.zeros(len(t), np.int32),
                             [FaceTag(part, "lens", "lens-edge", finish, face=last - first + 1)]))
    return TaggedMesh.concatenate(meshes)


def lens_elements(prescription: Prescription, semi_diameters, **kw) -> TaggedMesh:
    """Every glass group of the prescription as a solid: parts lens-1, lens-2, ... (a cemented
    group is one solid here; semi_diameters (S,) per surface, the group takes the largest)."""
    out = []
    for k, group in enumerate(prescription.lens_groups()):
        sd = max(float(semi_diameters[i]) for i in group)
        out.append(lens_element(prescription, group[0], group[-1], sd, part=f"lens-{k + 1}", **kw))
    return TaggedMesh.concatenate(out)


__all__ = ["rotation", "disk", "rectangle", "box", "sphere", "tube", "lens_element", "lens_elements"]
