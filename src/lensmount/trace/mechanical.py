"""Exact nearest hit of rays with the mechanical (non-optical) triangles of a scene.

Embree is float32: it only proposes a candidate triangle. The answer is decided in float64 on
the ray's own line, so a ray hits a triangle exactly when a float64 Möller–Trumbore
intersection says so (to ~1e-12 of its size), whatever float32 rounding did:

1. *Fat candidates.* Embree gets every triangle enlarged in its plane by `margin` (a few
   float32 roundings of the assembly size), as separate triangles. A ray whose float64 line
   crosses a triangle, even at its very edge, therefore crosses its fat copy in float32 too.
2. *Float64 decision.* The candidate is re-intersected in float64. A hit well inside it
   (farther than `margin` from its edges) is the answer. Near an edge, or when the float64
   line misses the candidate, every triangle sharing a vertex with it (its ring) is
   intersected too and the nearest float64 hit among them is the answer: at a seam, at a
   knife edge (a 50 µm land and its two faces), at a concave corner.
2b. *A nearer face within float32's noise.* Embree may order two crossings a few float32 roundings
   apart either way (a vane's face ending on a bore wall, crossed nanometres before the wall). So
   every face sharing no vertex with the answer's triangle whose box comes within `_BAND` margins
   of its box (listed once, at build), and which is not parallel to it, is solved in float64 too
   when its box and its plane pass within that band of the hit point; the nearest crossing wins.
   Elsewhere (no such face near the point, the common case) this costs one lookup.
3. *Relaunch along the line.* If nothing is hit near the candidate (the line passes a silhouette
   edge, or the candidate is the face the ray leaves), every triangle whose box comes near the
   stretch of line the relaunch steps over is intersected in float64 too: from where the
   candidate's own plane is crossed (or Embree's t, whichever is nearer) to the relaunch point,
   padded by the relaunch step. That stretch holds a face meeting the candidate's edge without
   sharing its vertices (a T-junction, e.g. a vane's root on a spacer's bore wall), and, for a ray
   grazing the face it leaves, the neighbouring face across a crease: Embree's float32 t along a
   ray at 0.02° to its face is tens of µm off, the neighbour within a µm. Only if none is hit
   there is the query relaunched from just beyond the candidate on the same line. The line is
   never shifted sideways and a hit is never moved.
4. *The face a ray leaves.* A hit at |t| ≤ `t_tol` (the ray starts on that face) counts only
   when the caller says what the ray left and the ray enters this face (its outward normal
   faces the ray): a ray leaving glass meets metal touching the glass (gap 0); a ray leaving a
   mechanical face meets the neighbouring face at a concave corner, never a face coplanar with
   the one it left. Such rays are launched `back` before their origin so that float32 rounding
   cannot put the launch point behind a face at distance 0.

What this cannot see: a second mechanical face within `margin` *beyond* a face the ray is
not allowed to hit (the face it leaves, or a silhouette it passes), unless the two share a
vertex. `margin` is 5e-7 of the assembly size (0.3 µm on the 608 mm reference design).
Glass-to-metal contacts are unaffected: optical faces live in their own Embree scene.
"""

from __future__ import annotations

import numpy as np

from lensmount.trace import kernels

_MARGIN_REL = 5e-7     # float32 candidate margin and relaunch step, relative to the assembly size
_BARY_TOL = 1e-12      # float64 inside test: barycentric tolerance (closes seams exactly)
_MAX_ROUNDS = 32
_BAND = 4.0            # float32 noise band about an accepted hit, in margins (rule 2b)
_EMBREE_MISS = 1e30


class MechanicalFaces:
    """The mechanical triangles `prims` (global indices) of a mesh, for exact nearest hits.

    vertices (V, 3) float64, triangles (T, 3), normals (T, 3) unit (outward for CAD solids),
    centre (3,) the float32 frame origin, extent (mm) the assembly size, t_tol (mm).
    """

    def __init__(self, vertices, triangles, normals, prims, centre, extent, t_tol):
        from embreex import rtcore_scene as rtcs  # lazy: keeps lensmount --help from loading embreex
        from embreex.mesh_construction import TriangleMesh

        self.prims = np.asarray(prims, np.int64)
        self.centre = centre
        self.margin = _MARGIN_REL * extent
        self.back = 2.0 * self.margin
        self.t_tol = t_tol
        self.queries = 0
        tri = triangles[self.prims]
        a, b, c = (vertices[tri[:, k]] for k in range(3))
        self._a, self._e1, self._e2 = a, b - a, c - a
        self._n = normals[self.prims]
        self._box = np.stack([np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)], axis=1)  # (T, 2, 3)
        # Altitudes: distance to edge k = barycentric λ_k × altitude_k (λ_0 opposite edge b–c).
        area2 = np.linalg.norm(np.cross(self._e1, self._e2), axis=1)
        lengths = np.column_stack([np.linalg.norm(c - b, axis=1), np.linalg.norm(c - a, axis=1),
                                   np.linalg.norm(b - a, axis=1)])
        self._alt = area2[:, None] / np.maximum(lengths, 1e-300)
        # Ring: triangles sharing a vertex position (also across parts that touch).
        _, vid = np.unique(vertices, axis=0, return_inverse=True)
        vid = vid.reshape(-1)[tri]
        order = np.argsort(vid.reshape(-1), kind="stable")
        self._vt = order // 3  # local triangle ids grouped by vertex
        counts = np.bincount(vid.reshape(-1), minlength=int(vid.max()) + 1 if len(vid) else 0)
        self._vt_ptr = np.concatenate([[0], np.cumsum(counts)])
        self._vid = vid
        # Faces beside each face, sharing none of its vertices (those are its ring): boxes within the
        # float32 noise band of its own (rule 2b).
        self._band = _BAND * self.margin
        self._beside_first, self._beside = kernels.box_pairs(self._box, np.ascontiguousarray(vid, np.int64),
                                                                   np.ascontiguousarray(self._n), self._band)
        self._grid = kernels.box_grid(self._box)  # the boxes by cell, for rule 3's search
        self.has_faces = len(self.prims) > 0
        if self.has_faces:
            # Fat copies: scaled about the incentre so every edge moves out by `margin`.
            per = lengths.sum(axis=1)
            incentre = (lengths[:, :1] * a + lengths[:, 1:2] * b + lengths[:, 2:] * c) / np.maximum(per, 1e-300)[:, None]
            r_in = area2 / np.maximum(per, 1e-300)
            grow = 1.0 + np.minimum(self.margin / np.maximum(r_in, 1e-300), 1.0)
            fat = np.stack([incentre + grow[:, None] * (v - incentre) for v in (a, b, c)], axis=1)
            self._embree = rtcs.EmbreeScene()
            TriangleMesh(self._embree, (fat.reshape(-1, 3) - centre).astype(np.float32),
                         np.arange(3 * len(tri), dtype=np.int32).reshape(-1, 3))

    # ------------------------------------------------------------------ float64 geometry

    def _crossings(self, local, o, d, leaving, left_normal):
        """Float64 Möller–Trumbore of rays (m,) with local triangles (m,), and which crossings are
        real hits (rule 4 of the module docstring): (t (m,) inf if parallel, λ (m, 3), valid (m,))."""
        return kernels.triangle_crossings(np.asarray(local, np.int64), o, d, np.asarray(leaving, np.bool_),
                                          left_normal, self._a, self._e1, self._e2, self._n, self.t_tol, _BARY_TOL)

    def _nearest_of(self, r, tri, oo, dd, leaving, left_normal, te, step, t64, loc) -> None:
        """For rays r (one row per triangle tri to try): the nearest float64 crossing not beyond the
        candidate's neighbourhood (te + 2 step) into t64 and loc, in place."""
        tr, _, good = self._crossings(tri, oo[r], dd[r], leaving[r], left_normal[r])
        good &= tr <= te[r] + 2.0 * step
        tr = np.where(good, tr, np.inf)
        best = np.full(len(te), np.inf)
        np.minimum.at(best, r, tr)
        win = good & (tr == best[r])
        t64[r[win]] = tr[win]
        loc[r[win]] = tri[win]

    def _ring(self, local):
        """Flattened ring of local triangles (m,): (row (k,), triangle (k,))."""
        rows, tris = [], []
        for corner in range(3):
            v = self._vid[local, corner]
            start, stop = self._vt_ptr[v], self._vt_ptr[v + 1]
            cnt = stop - start
            row = np.repeat(np.arange(len(local)), cnt)
            offs = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
            rows.append(row)
            tris.append(self._vt[np.repeat(start, cnt) + offs])
        return np.concatenate(rows), np.concatenate(tris)

    def _skipped(self, base, te, tc, cand, d, step):
        """The stretch of line (lo (m,), hi (m,), as ray parameters) a relaunch from te + step steps over
        after a candidate that is no hit (the face the ray leaves, a silhouette): from where its float64
        plane crossing tc or Embree's te puts it, whichever is nearer, to te + 2 step. Embree's t is
        float32: off by its coordinates' rounding (under `margin`) over the sine of the angle between
        the ray and the candidate's plane, tens of µm for a ray grazing the face it leaves, which
        crosses a neighbour at a crease within a µm. Never before this round's launch (the rounds
        before looked there), nor farther back than that rounding explains (a silhouette's plane
        crossing may lie anywhere)."""
        sine = np.abs(np.einsum("ij,ij->i", self._n[cand], d))
        noise = self.margin * (1.0 + 1.0 / np.maximum(sine, 1e-12))
        near = np.minimum(te, np.where(np.isfinite(tc), tc, te)) - self.margin
        return np.maximum(base, np.maximum(near, te - noise)), te + 2.0 * step

    def _boxes_near(self, points, pad):
        """Local triangles whose bounding box, padded by `pad`, holds each of points (m, 3):
        (row (k,), triangle (k,)); pad a number or one per point. It runs for rays passing a silhouette edge
        (~6 600 a case-1 pass, whose backward rays aim at the diaphragm's 50 µm edge) and for rays grazing
        the face they leave (Embree's t overshoots it); over every box that was 2 of a view map's 3 CPU
        seconds, through the grid of boxes a few milliseconds."""
        return kernels.boxes_near(points, self._box, pad, *self._grid)

    # ------------------------------------------------------------------ query

    def occluded(self, o, d, t_far, leaving):
        """(n,) bool: may a mechanical face lie on the rays' segments [0, t_far]? Exact in the
        conservative direction: every float64 crossing lies on a fat copy, so False means none
        (True may be a near miss: the caller then asks `nearest`)."""
        if not self.has_faces or len(o) == 0:
            return np.zeros(len(o), bool)
        base = np.where(leaving, -self.back, 0.0)
        start = o + base[:, None] * d
        self.queries += len(o)
        far = (t_far - base) * (1.0 + 1e-6) + self.margin
        res = self._embree.run((start - self.centre).astype(np.float32), d.astype(np.float32),
                               dists=far.astype(np.float32), query="OCCLUDED")
        return np.asarray(res) >= 0

    def nearest(self, o, d, leaving, left_normal):
        """Nearest mechanical hit of rays (n,): (t (n,) inf = none, prim (n,) global or -1, lost (n,)).

        leaving (n,) bool: the ray starts on a face the caller knows (it may then meet a face
        touching its origin, rule 4); left_normal (n, 3): that face's normal when it is
        mechanical, zeros otherwise (glass, or nothing).
        """
        n = len(o)
        t_hit = np.full(n, np.inf)
        prim = np.full(n, -1, np.int64)
        lost = np.zeros(n, bool)
        if not self.has_faces or n == 0:
            return t_hit, prim, lost
        base = np.where(leaving, -self.back, 0.0)  # launch point, as a parameter on the ray's line
        todo = np.arange(n)
        for round_ in range(_MAX_ROUNDS):
            if todo.size == 0:
                break
            oo, dd = o[todo], d[todo]
            start = oo + base[todo, None] * dd
            self.queries += len(todo)
            res = self._embree.run((start - self.centre).astype(np.float32), dd.astype(np.float32),
                                   query="INTERSECT", output=1)
            fat = res["primID"].astype(np.int64)
            te = res["tfar"].astype(np.float64)
            hit = (fat >= 0) & (te < _EMBREE_MISS)
            cand = np.where(hit, fat, 0)
            te = te + base[todo]
            t64 = np.full(len(todo), np.inf)
            loc = np.full(len(todo), -1, np.int64)
            # 2. The candidate alone, when the float64 line crosses it well inside its edges (a
            # self-hit there is simply skipped).
            tc, lam, valid = self._crossings(cand, oo, dd, leaving[todo], left_normal[todo])
            ok = hit & valid
            inside = np.min(lam * self._alt[cand], axis=1)  # distance of the crossing from the candidate's edges
            clear = hit & (inside >= self.margin)
            t64[clear & ok], loc[clear & ok] = tc[clear & ok], cand[clear & ok]
            # ... else (near or outside its edges) its ring: the nearest float64 hit among them
            # that is not beyond the candidate's neighbourhood.
            step = self.margin * 2.0 ** max(0, round_ - 8)
            near = np.flatnonzero(hit & ~clear)
            if near.size:
                row, tri = self._ring(cand[near])
                self._nearest_of(near[row], tri, oo, dd, leaving[todo], left_normal[todo], te, step, t64, loc)
            # 2b. A face nearer than the accepted hit by less than float32's noise (Embree may order the
            # two either way): any face whose box lies within the band of the hit point is solved in
            # float64 too when its plane passes within the band as well, and the nearest crossing wins (a
            # vane's face ending on a bore wall).
            got = np.flatnonzero(np.isfinite(t64))
            if got.size:
                row, tri = kernels.neighbours_near(oo[got] + t64[got, None] * dd[got], loc[got],
                                                   self._beside_first, self._beside, self._box, self._a, self._n,
                                                   self._band)
                if row.size:
                    t_near, l_near = np.full(len(todo), np.inf), np.full(len(todo), -1, np.int64)
                    self._nearest_of(got[row], tri, oo, dd, leaving[todo], left_normal[todo], te, step, t_near, l_near)
                    nearer = t_near < t64
                    t64[nearer], loc[nearer] = t_near[nearer], l_near[nearer]
            # 3. Nothing found: any face near the stretch of line the relaunch below steps over (a
            # T-junction; a face the ray leaves and its neighbour across a crease), unless that stretch
            # ends before the line can leave the candidate's face (its crossing as far inside as that).
            with np.errstate(invalid="ignore"):
                over_face = ~clear | ~(te + 2.0 * step <= tc + inside)
            beside = np.flatnonzero(hit & ~np.isfinite(t64) & over_face)
            if beside.size:
                lo, hi = self._skipped(base[todo[beside]], te[beside], tc[beside], cand[beside], dd[beside], step)
                row, tri = self._boxes_near(oo[beside] + (0.5 * (lo + hi))[:, None] * dd[beside],
                                            0.5 * (hi - lo) + 4.0 * step + self.margin)
                self._nearest_of(beside[row], tri, oo, dd, leaving[todo], left_normal[todo], te, step, t64, loc)
            done = ~hit | np.isfinite(t64)
            idx = todo[done & hit]
            t_hit[idx] = t64[done & hit]
            prim[idx] = self.prims[loc[done & hit]]
            # Nothing real here: relaunch from just beyond the candidate, on the same line.
            again = ~done
            base[todo[again]] = te[again] + step
            todo = todo[again]
        lost[todo] = True
        return t_hit, prim, lost


__all__ = ["MechanicalFaces"]
