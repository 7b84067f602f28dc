"""Tagged tessellation: every triangle keeps its part, CAD face and role.

The solid is meshed once (BRepMesh, so neighbouring faces share their edge
nodes), then read face by face (BRep_Tool.Triangulation per face, flipped for
reversed faces) so each triangle knows the face it came from. Nodes are merged by
position per part (seams and poles of revolved faces repeat them), degenerate
triangles dropped, and the part's mesh is checked watertight with manifold3d.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from lensmount.mesh import FaceTag, TaggedMesh

MERGE_TOL_MM = 1e-5


class MeshError(RuntimeError):
    """A part's tessellation is not a closed 2-manifold."""


def face_triangulations(solid, linear_mm: float, angular_deg: float):
    """[(face_index, vertices (n,3), triangles (m,3))] in `solid.faces()` order."""
    from OCP.BRep import BRep_Tool  # lazy: build123d/OCP take seconds to load; only solid modelling needs them
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.TopAbs import TopAbs_REVERSED
    from OCP.TopLoc import TopLoc_Location

    BRepMesh_IncrementalMesh(solid.wrapped, linear_mm, False, math.radians(angular_deg), True)
    out = []
    for k, f in enumerate(solid.faces()):
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(f.wrapped, loc)
        if tri is None:
            continue
        trsf = loc.Transformation()
        nodes = np.array([tri.Node(i).Transformed(trsf).Coord() for i in range(1, tri.NbNodes() + 1)],
                         dtype=np.float64).reshape(-1, 3)
        tris = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)],
                        dtype=np.int64).reshape(-1, 3) - 1
        if f.wrapped.Orientation() == TopAbs_REVERSED:
            tris = tris[:, ::-1]
        out.append((k, nodes, tris))
    return out


def merge_vertices(vertices: np.ndarray, triangles: np.ndarray, tol: float = MERGE_TOL_MM):
    """Weld nodes closer than tol; drop triangles that collapse. Returns (V', T', kept (T,) bool)."""
    if not len(vertices):
        return vertices, triangles, np.ones(len(triangles), bool)
    pairs = cKDTree(vertices).query_pairs(tol, output_type="ndarray")
    n = len(vertices)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)) if len(pairs) \
        else coo_matrix((n, n))
    _, parent = connected_components(graph, directed=False)
    roots, first, inverse = np.unique(parent, return_index=True, return_inverse=True)
    v = vertices[first]
    t = inverse[triangles]
    ok = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])
    return v, t[ok], ok


def check_watertight(name: str, vertices: np.ndarray, triangles: np.ndarray) -> None:
    """manifold3d accepts only closed, oriented 2-manifolds: raise MeshError otherwise."""
    mesh = manifold3d.Mesh(vert_properties=np.ascontiguousarray(vertices, dtype=np.float32),
                           tri_verts=np.ascontiguousarray(triangles, dtype=np.uint32))
    status = manifold3d.Manifold(mesh).status()
    if status != manifold3d.Error.NoError:
        raise MeshError(f"{name}: tessellation is not watertight ({status.name})")


def tessellate_part(solid, name: str, kind: str, finish: str, roles: list[tuple[str, int]],
                    linear_mm: float, angular_deg: float, check: bool = True,
                    finishes: list[str] | None = None, labels: list[str] | None = None,
                    assigned: list[str] | None = None) -> TaggedMesh:
    """One part's TaggedMesh; tags are per CAD face (role from `roles[face]`; finish, label and how the
    finish was assigned from `finishes[face]`, `labels[face]`, `assigned[face]` when given: a STEP part's
    faces)."""
    verts, tris, tags, table = [], [], [], []
    v0 = 0
    for k, nodes, t in face_triangulations(solid, linear_mm, angular_deg):
        role, surface = roles[k]
        table.append(FaceTag(name, kind, role, finishes[k] if finishes else finish, int(surface), int(k),
                             labels[k] if labels else "", assigned[k] if assigned else ""))
        verts.append(nodes)
        tris.append(t + v0)
        tags.append(np.full(len(t), len(table) - 1, np.int32))
        v0 += len(nodes)
    V = np.concatenate(verts)
    T = np.concatenate(tris)
    G = np.concatenate(tags)
    V, T, ok = merge_vertices(V, T)
    G = G[ok]
    if check:
        check_watertight(name, V, T)
    return TaggedMesh(V, T, G, table)


__all__ = ["tessellate_part", "merge_vertices", "check_watertight", "MeshError", "face_triangulations"]
