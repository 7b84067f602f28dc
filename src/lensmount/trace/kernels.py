"""Compiled per-ray kernels of the tracer's analytic steps (numba).

Why compiled: the profile of `Tracer.next_event` (CHANGELOG.md, "Compiled kernels") showed Embree itself a
small share; the time went to numpy temporaries around each query — the sequential step alone
built ~60 (n,) float64 arrays per call to find one conic crossing per ray. Here each ray is one
loop iteration over a few scalars: the same arithmetic, in the same order, as the numpy
formulas it replaces (no fastmath), so the crossings are the same numbers.

`cache=True`: a worker loads the compiled code from `__pycache__` instead of compiling again.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lensmount.trace.jit_cache import drop_damaged

# Columns of the per-surface table the sequential step reads (`face_table`); from REACH on, band b of reach
# as (lo, hi) in columns REACH + 2b, REACH + 2b + 1. One array, not ten: the compiled walk inlines `step_one`
# on every step, and numba takes and drops an atomic reference on each array passed to it there; ten
# arrays made those counts more than a third of the walk's time. HI_BELOW (the highest slab top of this surface
# and those before it) and LO_ABOVE (the lowest slab bottom of this one and those after it) bound the slab
# test's loop: surfaces before a HI_BELOW under the path, or from a LO_ABOVE over it, cannot overlap it.
UP, DOWN, SAFE, SLAB_LO, SLAB_HI, HI_BELOW, LO_ABOVE, REACH_INV, Z_VERTEX, CURVATURE, CONIC, REACH = range(12)


def face_table(up, down, safe, slab, reach, reach_inv, z_vertex, curvature, conic) -> np.ndarray:
    """(k_n, REACH + 2 bands) float64 in the columns above (up/down: surface numbers, exact as floats)."""
    return np.column_stack([up, down, safe, slab[:, 0], slab[:, 1], np.maximum.accumulate(slab[:, 1]),
                            np.minimum.accumulate(slab[::-1, 0])[::-1], reach_inv, z_vertex, curvature, conic,
                            reach.reshape(len(reach), -1)]).astype(np.float64)


@njit(cache=True, inline="always")
def _conic_root_pair(c, k1, zv, t_min, ox, oy, oz0, dx, dy, dz):
    """Both float64 crossings of one ray with a conic (curvature c, 1 + conic k1, vertex zv): inf
    where none, behind t_min or off the vertex sheet (as `Tracer._conic_roots`)."""
    oz = oz0 - zv
    a = c * (dx * dx + dy * dy + k1 * dz * dz)
    b = c * (ox * dx + oy * dy + k1 * oz * dz) - dz
    cc = c * (ox * ox + oy * oy + k1 * oz * oz) - 2.0 * oz
    disc = b * b - a * cc
    ok = disc >= 0.0
    q = b + math.copysign(math.sqrt(disc if ok else 0.0), b)
    t1 = -cc / q if (ok and q != 0.0) else np.inf
    t2 = -q / a if (ok and a != 0.0) else np.inf
    if not (math.isfinite(t1) and t1 > t_min and k1 * c * (oz + t1 * dz) <= 1.0 + 1e-12):
        t1 = np.inf
    if not (math.isfinite(t2) and t2 > t_min and k1 * c * (oz + t2 * dz) <= 1.0 + 1e-12):
        t2 = np.inf
    return t1, t2


@njit(cache=True)
def conic_roots(c, k1, zv, t_min, o, d):
    """(t1, t2) (n,) of rays o, d (n, 3) with one conic surface per ray (c, k1, zv (n,))."""
    n = o.shape[0]
    t1 = np.empty(n)
    t2 = np.empty(n)
    for i in range(n):
        t1[i], t2[i] = _conic_root_pair(c[i], k1[i], zv[i], t_min, o[i, 0], o[i, 1], o[i, 2],
                                        d[i, 0], d[i, 1], d[i, 2])
    return t1, t2


@njit(cache=True, inline="always")
def step_one(lk, ox, oy, oz, dx, dy, dz, ts, faces, t_min):
    """One ray of `sequential_step`: (sure, t, surface).

    A ray leaving the last faceted surface in its direction (no next one) can only meet that
    surface again; a ray that left no surface (lk < 0) and starts outside every slab on its way
    in can only meet the first faceted surface it travels toward: the same proof (safe radius,
    no other slab entered) covers both.
    """
    k_n = faces.shape[0]
    if lk < 0:
        nxt = -1
        for k in range(k_n):
            if math.isfinite(faces[k, SLAB_LO]) and (dz < 0.0 or nxt < 0):
                nxt = k  # the first faceted surface going +z, the last going -z
        if (nxt < 0 or not (faces[nxt, SAFE] > 0.0)
                or not (oz < faces[nxt, SLAB_LO] if dz > 0.0 else oz > faces[nxt, SLAB_HI])):
            return False, np.inf, -1
    else:
        kk = min(lk, k_n - 1)
        nxt = int(faces[kk, UP] if dz > 0.0 else faces[kk, DOWN])
        if not (faces[kk, SAFE] > 0.0) or (nxt >= 0 and not (faces[min(nxt, k_n - 1), SAFE] > 0.0)):
            return False, np.inf, -1
    good = True
    tb = np.inf
    sb = -1
    for j in range(2):
        k = lk if j == 0 else nxt
        if k < 0:
            continue
        r1, r2 = _conic_root_pair(faces[k, CURVATURE], 1.0 + faces[k, CONIC], faces[k, Z_VERTEX], t_min, ox, oy, oz,
                                  dx, dy, dz)
        for m in range(2):
            t = r1 if m == 0 else r2
            before = t < ts
            tt = t if before else 0.0
            px = ox + tt * dx
            py = oy + tt * dy
            inside = px * px + py * py <= faces[k, SAFE] * faces[k, SAFE]
            if before and not inside:  # past the safe radius it may or may not be glass: decline
                good = False
            if before and inside and t < tb:
                tb = t
                sb = k
    # The path up to the hit (or the metal) must not enter any other surface's slab.
    t_end = min(tb, ts)
    if math.isfinite(t_end):
        z1 = oz + t_end * dz
    else:
        z1 = np.inf if dz > 0 else -np.inf
    lo, hi = min(oz, z1), max(oz, z1)
    if not good:
        return False, np.inf, -1
    r_far = -1.0
    first = min(lk, nxt)
    for k in range(first if first > 0 and faces[first - 1, HI_BELOW] < lo else 0, k_n):
        if faces[k, LO_ABOVE] > hi:
            break
        if k != lk and k != nxt and lo <= faces[k, SLAB_HI] and hi >= faces[k, SLAB_LO]:
            # In the slab: still clear if the facets that come as near the axis as the path (its
            # distance from the axis is largest at an end) lie outside its z range.
            if not math.isfinite(t_end):
                return False, np.inf, -1
            if r_far < 0.0:
                ex, ey = ox + t_end * dx, oy + t_end * dy
                r_far = math.sqrt(max(ox * ox + oy * oy, ex * ex + ey * ey))
            b = REACH + 2 * min(int(r_far * faces[k, REACH_INV]) + 1, (faces.shape[1] - REACH) // 2 - 1)
            if lo <= faces[k, b + 1] and hi >= faces[k, b]:
                return False, np.inf, -1
    return True, tb, sb


@njit(cache=True)
def sequential_step(left, o, d, t_stop, faces, t_min):
    """`Tracer._sequential_step` per ray: (sure (n,) bool, t (n,), surface (n,) int64).

    left (n,): the optical surface each ray just left (-1: none); faces: `face_table` of up/down (the next
    faceted surface above/below, -1: none), the facets' safe radius, their padded z range (slab), that range
    by radius (reach, reach_inv) and the conic (`Tracer._optical_faces`).
    """
    n = o.shape[0]
    sure = np.zeros(n, np.bool_)
    t_best = np.full(n, np.inf)
    s_best = np.full(n, -1, np.int64)
    for i in range(n):
        sure[i], t_best[i], s_best[i] = step_one(left[i], o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2],
                                                 t_stop[i], faces, t_min)
    return sure, t_best, s_best


@njit(cache=True)
def triangle_crossings(local, o, d, leaving, left_normal, a, e1, e2, normal, t_tol, bary_tol):
    """Float64 Möller–Trumbore of rays o, d (m, 3) with triangles `local` (m,) (corner a, edges e1,
    e2, unit normal), and which crossings are real hits (`MechanicalFaces._crossing` and `_valid`):
    (t (m,) inf where parallel, λ (m, 3) barycentrics, valid (m,) bool)."""
    m = local.shape[0]
    t_out = np.empty(m)
    lam = np.empty((m, 3))
    valid = np.zeros(m, np.bool_)
    for i in range(m):
        j = local[i]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        ax, ay, az = e1[j, 0], e1[j, 1], e1[j, 2]
        bx, by, bz = e2[j, 0], e2[j, 1], e2[j, 2]
        px, py, pz = dy * bz - dz * by, dz * bx - dx * bz, dx * by - dy * bx  # d × e2
        det = ax * px + ay * py + az * pz
        ok = abs(det) > 1e-300
        inv = 1.0 / det if ok else 0.0
        tx, ty, tz = o[i, 0] - a[j, 0], o[i, 1] - a[j, 1], o[i, 2] - a[j, 2]
        u = (tx * px + ty * py + tz * pz) * inv
        qx, qy, qz = ty * az - tz * ay, tz * ax - tx * az, tx * ay - ty * ax  # tvec × e1
        v = (dx * qx + dy * qy + dz * qz) * inv
        t = (bx * qx + by * qy + bz * qz) * inv if ok else np.inf
        l0 = 1.0 - u - v
        t_out[i] = t
        lam[i, 0], lam[i, 1], lam[i, 2] = l0, u, v
        inside = l0 >= -bary_tol and u >= -bary_tol and v >= -bary_tol and math.isfinite(t)
        if not inside:
            continue
        if t > t_tol:
            valid[i] = True
            continue
        # At the ray's origin: a hit only for a ray leaving a face, entering this one, and this one
        # not coplanar with the face it leaves.
        if not (abs(t) <= t_tol and leaving[i]):
            continue
        nx, ny, nz = normal[j, 0], normal[j, 1], normal[j, 2]
        enters = nx * dx + ny * dy + nz * dz < 0.0
        coplanar = (abs(nx * left_normal[i, 0] + ny * left_normal[i, 1] + nz * left_normal[i, 2]) > 1.0 - 1e-9
                    and abs(nx * tx + ny * ty + nz * tz) <= t_tol)
        valid[i] = enters and not coplanar
    return t_out, lam, valid
def box_pairs(box, vid, normal, pad):
    """(first (T + 1,), other (k,)): for each triangle, the others sharing no vertex with it (vid (T, 3):
    vertex ids) and not parallel to it (unit normal (T, 3); see `neighbours_near`) whose bounding box
    (box (T, 2, 3): lo, hi) comes within pad of its own (CSR: triangle i's are other[first[i]:first[i + 1]],
    ascending). Candidates come from a grid of the boxes grown by a little more than pad (`box_grid`),
    each pair tested once, in the cell holding the low corner of the grown boxes' overlap; the test
    itself is on the boxes as given. (A sweep along x tested every pair overlapping in x: on a lens
    mount, a barrel's triangles all do, 2 s of each worker's 2.5 s tracer build on the double Gauss.)"""
    box = np.ascontiguousarray(box, np.float64).reshape(-1, 2, 3)
    grow = float(pad) + 1e-9  # the grid's boxes hold every pair within 2·pad whatever the rounding
    grown = np.stack([box[:, 0] - grow, box[:, 1] + grow], axis=1)
    origin, cell, dims, first, member = box_grid(grown)
    return _pairs_in_cells(box, grown, np.ascontiguousarray(vid, np.int64), np.ascontiguousarray(normal, np.float64),
                           float(pad), origin, cell, dims, first, member)


@njit(cache=True)
def _pairs_in_cells(box, grown, vid, normal, pad, origin, cell, dims, first, member):
    """`box_pairs` from the grid (origin, cell, dims, first, member) of the grown boxes: counted, then filled."""
    t_n = box.shape[0]
    count = np.zeros(t_n, np.int64)
    other = np.empty(0, np.int64)
    start = np.zeros(t_n + 1, np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            start[1:] = np.cumsum(count)
            other = np.empty(start[t_n], np.int64)
            count[:] = 0
        for c in range(first.shape[0] - 1):
            for a in range(first[c], first[c + 1]):
                i = member[a]
                for b in range(a + 1, first[c + 1]):
                    j = member[b]
                    near = True
                    for ax in range(3):
                        near = near and box[j, 0, ax] <= box[i, 1, ax] + 2.0 * pad and box[i, 0, ax] <= box[j, 1, ax] + 2.0 * pad
                    if not near:
                        continue
                    ci = _grid_index(max(grown[i, 0, 0], grown[j, 0, 0]), origin[0], cell[0], dims[0])
                    cj = _grid_index(max(grown[i, 0, 1], grown[j, 0, 1]), origin[1], cell[1], dims[1])
                    ck = _grid_index(max(grown[i, 0, 2], grown[j, 0, 2]), origin[2], cell[2], dims[2])
                    if (ci * dims[1] + cj) * dims[2] + ck != c:
                        continue  # the pair's own cell is another one they share
                    shared = False
                    for u in range(3):
                        for v in range(3):
                            shared = shared or vid[i, u] == vid[j, v]
                    parallel = abs(normal[i, 0] * normal[j, 0] + normal[i, 1] * normal[j, 1]
                                   + normal[i, 2] * normal[j, 2]) >= 1.0 - 1e-9
                    if shared or parallel:
                        continue
                    if pass_ == 1:
                        other[start[i] + count[i]] = j
                        other[start[j] + count[j]] = i
                    count[i] += 1
                    count[j] += 1
    for i in range(t_n):
        other[start[i]:start[i + 1]] = np.sort(other[start[i]:start[i + 1]])
    return start, other


@njit(cache=True, inline="always")
def _in_padded_box(box, t, qx, qy, qz, pad):
    """Whether (qx, qy, qz) lies in triangle t's bounding box (box (T, 2, 3): lo, hi) padded by pad."""
    return (box[t, 0, 0] - pad <= qx and qx <= box[t, 1, 0] + pad and box[t, 0, 1] - pad <= qy
            and qy <= box[t, 1, 1] + pad and box[t, 0, 2] - pad <= qz and qz <= box[t, 1, 2] + pad)


@njit(cache=True)
def neighbours_near(points, own, first, other, box, corner, normal, pad):
    """(row (k,), triangle (k,)): for each point (m, 3) on triangle own (m,), the triangles listed
    beside it (`box_pairs`) whose bounding box, padded by pad, holds the point and whose plane (a
    corner, unit normal) passes within pad of it, not parallel to own's (a coplanar face is crossed at
    the same distance, never nearer); rows in order."""
    m = points.shape[0]
    count = 0
    row = np.empty(0, np.int64)
    tri = np.empty(0, np.int64)
    for pass_ in range(2):  # count, then fill
        if pass_ == 1:
            row = np.empty(count, np.int64)
            tri = np.empty(count, np.int64)
            count = 0
        for i in range(m):
            qx, qy, qz = points[i, 0], points[i, 1], points[i, 2]
            o = own[i]
            for s in range(first[o], first[o + 1]):
                t = other[s]
                if (_in_padded_box(box, t, qx, qy, qz, pad)
                        and abs(normal[t, 0] * (qx - corner[t, 0]) + normal[t, 1] * (qy - corner[t, 1])
                                + normal[t, 2] * (qz - corner[t, 2])) <= pad
                        and abs(normal[t, 0] * normal[o, 0] + normal[t, 1] * normal[o, 1]
                                + normal[t, 2] * normal[o, 2]) < 1.0 - 1e-9):
                    if pass_ == 1:
                        row[count] = i
                        tri[count] = t
                    count += 1
    return row, tri


GRID_CELLS_MAX = 64  # cells per axis of the box grid (`box_grid`)
GRID_QUERY_CELLS_MAX = 512  # a query spanning more cells (a relaunch's wide pad) tests every box instead


def box_grid(box):
    """A uniform grid over the boxes (box (T, 2, 3): lo, hi), for `boxes_near`: (origin (3,), cell edge
    (3,), dims (3,), first (cells + 1,), member (k,)), each box listed (CSR, ascending) in every cell its
    box overlaps. About 2 cells per axis per ∛T, at most GRID_CELLS_MAX: on a 5 × 10⁴-face mount ~60 boxes a
    cell where a brute-force query tests all of them (on case 1 that search was 2 s of a pass's 3 s view map)."""
    box = np.ascontiguousarray(box, np.float64).reshape(-1, 2, 3)
    t_n = len(box)
    side = int(min(GRID_CELLS_MAX, max(1, round(2.0 * t_n ** (1.0 / 3.0)))))
    if t_n == 0:
        return np.zeros(3), np.ones(3), np.ones(3, np.int64), np.zeros(2, np.int64), np.zeros(0, np.int64)
    lo, hi = box[:, 0].min(axis=0), box[:, 1].max(axis=0)
    dims = np.full(3, side, np.int64)
    cell = np.where(hi > lo, (hi - lo) / dims, 1.0)
    first, member = _grid_members(box, lo, cell, dims)
    return lo, cell, dims, first, member


@njit(cache=True, inline="always")
def _grid_index(x, lo, cell, dim):
    """Cell of coordinate x along one axis, clipped to the grid (monotone in x)."""
    i = math.floor((x - lo) / cell)
    return int(min(max(i, 0.0), dim - 1.0))


@njit(cache=True, inline="always")
def _cell_span(lo, hi, origin, cell, dims):
    """(a0, a1, b0, b1, c0, c1): the cells, first and last along each axis, that the box [lo, hi] overlaps
    in the grid (origin, cell edge, dims), clipped to it."""
    return (_grid_index(lo[0], origin[0], cell[0], dims[0]), _grid_index(hi[0], origin[0], cell[0], dims[0]),
            _grid_index(lo[1], origin[1], cell[1], dims[1]), _grid_index(hi[1], origin[1], cell[1], dims[1]),
            _grid_index(lo[2], origin[2], cell[2], dims[2]), _grid_index(hi[2], origin[2], cell[2], dims[2]))


@njit(cache=True)
def _grid_members(box, lo, cell, dims):
    """CSR (first, member) of the boxes in each cell, boxes ascending in a cell (counted, then filled)."""
    n_cells = dims[0] * dims[1] * dims[2]
    first = np.zeros(n_cells + 1, np.int64)
    member = np.empty(0, np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            for c in range(n_cells):
                first[c + 1] += first[c]
            member = np.empty(first[n_cells], np.int64)
            fill = first[:-1].copy()
        for t in range(box.shape[0]):
            a0, a1, b0, b1, c0, c1 = _cell_span(box[t, 0], box[t, 1], lo, cell, dims)
            for i in range(a0, a1 + 1):
                for j in range(b0, b1 + 1):
                    for k in range(c0, c1 + 1):
                        c = (i * dims[1] + j) * dims[2] + k
                        if pass_ == 0:
                            first[c + 1] += 1
                        else:
                            member[fill[c]] = t
                            fill[c] += 1
    return first, member


def boxes_near(points, box, pad, lo, cell, dims, first, member):
    """(row (k,), triangle (k,)): the triangles whose bounding box (box (T, 2, 3): lo, hi), padded by
    pad (a number, or one per point), holds each of points (m, 3); rows in order, triangles ascending
    within a row. The same comparisons as the numpy test (lo - pad <= q <= hi + pad), on the boxes
    listed in the grid cells (`box_grid`) that [q - pad, q + pad] overlaps, widened by `slack` for the
    rounding of those comparisons (a box that holds the point lies in one of them); every box when that
    is many cells. A point with a non-finite coordinate is in no box (every comparison with it is false)."""
    points = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    pads = np.ascontiguousarray(np.broadcast_to(np.asarray(pad, np.float64), (len(points),)))
    return _boxes_near(points, box, pads, lo, cell, dims, first, member)


@njit(cache=True)
def _boxes_near(points, box, pads, lo, cell, dims, first, member):
    """`boxes_near` with one pad per point."""
    m, t_n = points.shape[0], box.shape[0]
    scale = 0.0
    for a in range(3):
        scale = max(scale, abs(lo[a]), abs(lo[a] + dims[a] * cell[a]))
    seen = np.full(t_n, -1, np.int64)
    found = np.empty(t_n, np.int64)
    count = 0
    row = np.empty(0, np.int64)
    tri = np.empty(0, np.int64)
    for pass_ in range(2):  # count, then fill
        if pass_ == 1:
            row = np.empty(count, np.int64)
            tri = np.empty(count, np.int64)
            count = 0
        for i in range(m):
            qx, qy, qz = points[i, 0], points[i, 1], points[i, 2]
            if not (math.isfinite(qx) and math.isfinite(qy) and math.isfinite(qz)):
                continue
            pad = pads[i]
            slack = pad + 1e-9 * (scale + pad)
            a0, a1, b0, b1, c0, c1 = _cell_span((qx - slack, qy - slack, qz - slack),
                                                (qx + slack, qy + slack, qz + slack), lo, cell, dims)
            n_found = 0
            if (a1 - a0 + 1) * (b1 - b0 + 1) * (c1 - c0 + 1) > GRID_QUERY_CELLS_MAX:
                for t in range(t_n):
                    found[n_found] = t
                    n_found += 1
            else:
                stamp = pass_ * m + i
                for a in range(a0, a1 + 1):
                    for b in range(b0, b1 + 1):
                        for c in range(c0, c1 + 1):
                            cc = (a * dims[1] + b) * dims[2] + c
                            for s in range(first[cc], first[cc + 1]):
                                t = member[s]
                                if seen[t] != stamp:
                                    seen[t] = stamp
                                    found[n_found] = t
                                    n_found += 1
                found[:n_found].sort()
            for s in range(n_found):
                t = found[s]
                if _in_padded_box(box, t, qx, qy, qz, pad):
                    if pass_ == 1:
                        row[count] = i
                        tri[count] = t
                    count += 1
    return row, tri


__all__ = ["conic_roots", "sequential_step", "triangle_crossings", "face_table", "box_pairs", "neighbours_near",
           "box_grid", "boxes_near"]

drop_damaged(globals())  # a damaged cache file is compiled again, not loaded (trace.jit_cache)
