"""The k nearest of a set of points, compiled: a uniform grid (cell list) searched ring by ring,
or for few points, queries grouped by cell sharing one list of possible neighbours.

The view map asks two neighbour questions of every hit point each pass: r_0, the distance to its
k-th neighbour on the same face (`radius.initial_radii`), and the 24 boundary segments whose
midpoints are nearest (`radius.FaceBoundaries`). scipy's cKDTree answered both, ~1.5 s of a
case-2 pass's ~3.5 s; this grid answers them with the same numbers:

- a distance is summed as cKDTree sums it, ((dx² + dy²) + dz²), then its square root: the k-th
  neighbour's distance is the same float;
- the k found are the k smallest by (squared distance, index) and come back in that order, so
  the set and the order are cKDTree's wherever the distances differ. On an exact tie cKDTree's
  choice follows its tree; here the smaller index wins (the k-th distance is the same either way).

The grid: points sorted by cell (counting sort); the cell size makes about PER_CELL points a cell
over the extents that are not flat (a face's hit points fill a 2-D sheet of a 3-D box). A query
visits its own cell, then the shells of cells around it one ring at a time, and stops when its
k-th distance is smaller than the distance to any cell not yet visited. Against a few hundred
points (a face's rim segments, 480 on case 2's faces, queried by up to 7 × 10⁴ hit points) the
queries are grouped instead, by cell of their own grid: one scan of the points a group, then
each query checks only the group's possible neighbours (`_k_nearest_grouped`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PER_CELL = 2  # points per occupied cell of the grid, on average
FEW_POINTS = 1024  # up to this many points, queries share the search in groups of ~QUERIES_PER_GROUP
QUERIES_PER_GROUP = 32
MAX_CELLS_PER_POINT = 16  # the grid's size limit


@njit(cache=True)
def _cell_size(lo, hi, n, per_cell):
    """Edge of a cubic cell giving ~n / per_cell cells over the box's extents that are not flat."""
    e = np.sort(hi - lo)[::-1]
    cells = max(1.0, n / per_cell)
    for dim in range(3, 0, -1):
        volume = 1.0
        for i in range(dim):
            volume *= e[i]
        c = (volume / cells) ** (1.0 / dim)
        if c > 0.0 and math.isfinite(c) and e[dim - 1] >= c:
            return c
    return e[0] if e[0] > 0.0 and math.isfinite(e[0]) else 1.0


@njit(cache=True)
def _grid(points, per_cell):
    """(origin (3,), cell edge, dims (3,), order (n,): point indices sorted by cell, start (cells + 1,)).

    The first cell size assumes the points fill the box's extents evenly; hit points crowd
    (a sheet inside a 3-D box, bright spots), so while the occupied cells hold more than twice
    per_cell on average the cells shrink (as a sheet's occupied cells grow: by the square root),
    within MAX_CELLS_PER_POINT cells a point."""
    n = points.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for a in range(3):
        lo[a] = points[:, a].min()
        hi[a] = points[:, a].max()
    c = _cell_size(lo, hi, n, per_cell)
    dims = np.empty(3, np.int64)
    cell = np.empty(n, np.int64)
    for attempt in range(4):
        for a in range(3):
            dims[a] = min(int((hi[a] - lo[a]) / c) + 1, 1 << 20)
        for i in range(n):
            cell[i] = _cell_of(points[i, 0], points[i, 1], points[i, 2], lo, c, dims)
        start = np.zeros(dims[0] * dims[1] * dims[2] + 1, np.int64)
        for i in range(n):
            start[cell[i] + 1] += 1
        occupied = 0
        for j in range(1, start.size):
            occupied += start[j] > 0
        crowd = n / max(occupied, 1)
        finer = math.sqrt(crowd / per_cell)
        if crowd <= 2.0 * per_cell or (start.size - 1) * finer**3 > MAX_CELLS_PER_POINT * n or attempt == 3:
            break
        c /= finer
    for j in range(1, start.size):
        start[j] += start[j - 1]
    return lo, c, dims, _sorted_by_cell(cell, start), start


@njit(cache=True)
def _sorted_by_cell(cell, start):
    """Indices sorted by cell (a counting sort; index order within a cell)."""
    fill = start[:-1].copy()
    order = np.empty(cell.size, np.int64)
    for i in range(cell.size):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return order


@njit(cache=True, inline="always")
def _axis_cell(x, lo, c, dim):
    i = int(math.floor((x - lo) / c)) if math.isfinite(x) else 0
    return min(max(i, 0), dim - 1)


@njit(cache=True, inline="always")
def _cell_of(x, y, z, lo, c, dims):
    return (_axis_cell(x, lo[0], c, dims[0]) * dims[1] + _axis_cell(y, lo[1], c, dims[1])) * dims[2] \
        + _axis_cell(z, lo[2], c, dims[2])


@njit(cache=True, inline="always")
def _scan(row, x, y, z, by_cell, order, start, bd, bi, found, k):
    """Offer the points of one cell to the query's k best (bd, bi ascending by (d², index)); the new count.
    by_cell: the points in cell order (points[order]), so a cell's points are read from consecutive memory."""
    for s in range(start[row], start[row + 1]):
        p = order[s]
        dx, dy, dz = x - by_cell[s, 0], y - by_cell[s, 1], z - by_cell[s, 2]
        d2 = (dx * dx + dy * dy) + dz * dz  # cKDTree's order of summation
        found = _offer(d2, p, bd, bi, found, k)
    return found


@njit(cache=True, inline="always")
def _offer(d2, p, bd, bi, found, k):
    """Point p at squared distance d2 into a query's k best (bd, bi ascending by (d², index)); the new count."""
    if found == k and (d2 > bd[k - 1] or (d2 == bd[k - 1] and p > bi[k - 1])):
        return found
    m = found if found < k else k - 1
    while m > 0 and (bd[m - 1] > d2 or (bd[m - 1] == d2 and bi[m - 1] > p)):
        bd[m] = bd[m - 1]
        bi[m] = bi[m - 1]
        m -= 1
    bd[m] = d2
    bi[m] = p
    return found + 1 if found < k else found


@njit(cache=True)
def _k_nearest(points, queries, k, per_cell):
    """(d² (Q, k), index (Q, k)): each query's k nearest points, ascending by (d², index)."""
    lo, c, dims, order, start = _grid(points, per_cell)
    by_cell = np.empty((order.size, 3))
    for s in range(order.size):
        by_cell[s] = points[order[s]]
    q_n = queries.shape[0]
    best_d = np.empty((q_n, k))
    best_i = np.empty((q_n, k), np.int64)
    scale = max(np.abs(lo).max(), np.abs(lo + dims * c).max())
    # A point's cell and the cell walls are rounded: the stopping bound is lowered by a few ulps.
    slack = 1e-9 * c + 1e-14 * scale
    q_cell = np.empty(q_n, np.int64)
    q_start = np.zeros(start.size, np.int64)
    for q in range(q_n):
        q_cell[q] = _cell_of(queries[q, 0], queries[q, 1], queries[q, 2], lo, c, dims)
        q_start[q_cell[q] + 1] += 1
    for j in range(1, q_start.size):
        q_start[j] += q_start[j - 1]
    # The queries in cell order, neighbours one after the other (their cells stay cached); read and
    # answered in that order from consecutive memory, the answers put in place at the end: hit points
    # come in pixel order, scattered over their face, and a search reading and writing them in place
    # waited on memory for most of its time.
    q_order = _sorted_by_cell(q_cell, q_start)
    q_by_cell = np.empty((q_n, 3))
    for s in range(q_n):
        q_by_cell[s] = queries[q_order[s]]
    sorted_d = np.empty((q_n, k))
    sorted_i = np.empty((q_n, k), np.int64)
    for s in range(q_n):
        x, y, z = q_by_cell[s, 0], q_by_cell[s, 1], q_by_cell[s, 2]
        cx = _axis_cell(x, lo[0], c, dims[0])
        cy = _axis_cell(y, lo[1], c, dims[1])
        cz = _axis_cell(z, lo[2], c, dims[2])
        bd = sorted_d[s]
        bi = sorted_i[s]
        found = 0
        ring = 0
        while True:
            x0, x1 = max(cx - ring, 0), min(cx + ring, dims[0] - 1)
            y0, y1 = max(cy - ring, 0), min(cy + ring, dims[1] - 1)
            z0, z1 = max(cz - ring, 0), min(cz + ring, dims[2] - 1)
            for i in range(x0, x1 + 1):
                for j in range(y0, y1 + 1):
                    row = (i * dims[1] + j) * dims[2]
                    if abs(i - cx) == ring or abs(j - cy) == ring:  # on the shell: the whole column
                        for kz in range(z0, z1 + 1):
                            found = _scan(row + kz, x, y, z, by_cell, order, start, bd, bi, found, k)
                    else:  # inside the shell's square: only its two z walls are new
                        if cz - ring >= 0:
                            found = _scan(row + cz - ring, x, y, z, by_cell, order, start, bd, bi, found, k)
                        if cz + ring < dims[2]:
                            found = _scan(row + cz + ring, x, y, z, by_cell, order, start, bd, bi, found, k)
            # The nearest point not yet visited lies beyond one of the walls of the visited block.
            wall = np.inf
            if x0 > 0:
                wall = min(wall, x - (lo[0] + x0 * c))
            if x1 < dims[0] - 1:
                wall = min(wall, lo[0] + (x1 + 1) * c - x)
            if y0 > 0:
                wall = min(wall, y - (lo[1] + y0 * c))
            if y1 < dims[1] - 1:
                wall = min(wall, lo[1] + (y1 + 1) * c - y)
            if z0 > 0:
                wall = min(wall, z - (lo[2] + z0 * c))
            if z1 < dims[2] - 1:
                wall = min(wall, lo[2] + (z1 + 1) * c - z)
            if wall == np.inf:
                break
            wall = max(wall - slack, 0.0)
            if found == k and bd[k - 1] < wall * wall:
                break
            ring += 1
    for s in range(q_n):
        best_d[q_order[s]] = sorted_d[s]
        best_i[q_order[s]] = sorted_i[s]
    return best_d, best_i


@njit(cache=True)
def _k_nearest_grouped(points, queries, k, per_group):
    """`_k_nearest` for few points and many queries (a face's rim segments and its hit points): the
    queries grouped by cell of their own grid (~per_group a cell); a group's possible neighbours,
    found once by a scan of all points, are the points within D + 2h of the group's centre (D: the
    centre's k-th distance, h: the group's farthest query from it); each query then scans those."""
    n = points.shape[0]
    q_n = queries.shape[0]
    best_d = np.empty((q_n, k))
    best_i = np.empty((q_n, k), np.int64)
    if q_n == 0:
        return best_d, best_i
    _, _, _, order, start = _grid(queries, per_group)
    scale = max(np.abs(points).max(), np.abs(queries).max())
    d_centre = np.empty(n)
    near = np.empty(n, np.int64)
    for g in range(start.size - 1):
        first, last = start[g], start[g + 1]
        if first == last:
            continue
        lo = queries[order[first]].copy()
        hi = lo.copy()
        for s in range(first + 1, last):
            for a in range(3):
                lo[a] = min(lo[a], queries[order[s], a])
                hi[a] = max(hi[a], queries[order[s], a])
        cx, cy, cz = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])
        h = 0.0
        for s in range(first, last):
            q = order[s]
            dx, dy, dz = queries[q, 0] - cx, queries[q, 1] - cy, queries[q, 2] - cz
            h = max(h, math.sqrt((dx * dx + dy * dy) + dz * dz))
        for p in range(n):
            dx, dy, dz = points[p, 0] - cx, points[p, 1] - cy, points[p, 2] - cz
            d_centre[p] = math.sqrt((dx * dx + dy * dy) + dz * dz)
        reach = np.partition(d_centre, k - 1)[k - 1]
        # Margins over the triangle inequality's reach for the rounding of every distance above.
        reach = (reach + 2.0 * h) * (1.0 + 1e-9) + 1e-14 * scale
        m = 0
        for p in range(n):
            if d_centre[p] <= reach or not math.isfinite(d_centre[p]):
                near[m] = p
                m += 1
        # Nearest the centre first: a query's k best fill early and the rest mostly fail one comparison.
        near[:m] = near[:m][np.argsort(d_centre[near[:m]])]
        for s in range(first, last):
            q = order[s]
            x, y, z = queries[q, 0], queries[q, 1], queries[q, 2]
            bd = best_d[q]
            bi = best_i[q]
            found = 0
            for j in range(m):
                p = near[j]
                dx, dy, dz = x - points[p, 0], y - points[p, 1], z - points[p, 2]
                d2 = (dx * dx + dy * dy) + dz * dz
                found = _offer(d2, p, bd, bi, found, k)
    return best_d, best_i


def k_nearest(points: np.ndarray, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(distance (Q, k), index (Q, k)) of the k points (N, 3) nearest each query (Q, 3), nearest
    first (ties: the smaller index first); cKDTree(points).query(queries, k)'s numbers. 1 ≤ k ≤ N."""
    d2, idx = _k_nearest_squared(points, queries, k)
    return np.sqrt(d2), idx


def nearest_indices(points: np.ndarray, queries: np.ndarray, k: int) -> np.ndarray:
    """(Q, k) `k_nearest`'s indices alone (the distances are not taken: a face's boundary candidates)."""
    return _k_nearest_squared(points, queries, k)[1]


def _k_nearest_squared(points, queries, k: int):
    """(d² (Q, k), index (Q, k)) of `k_nearest`. Up to FEW_POINTS points (a face's rim segments, a
    subsample) the queries share the work in groups (`_k_nearest_grouped`); more (a face's hit points
    among themselves), each searches the points' grid (`_k_nearest`). Both give the same answer; the
    choice is speed alone."""
    points = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    queries = np.ascontiguousarray(queries, np.float64).reshape(-1, 3)
    if not 1 <= k <= len(points):
        raise ValueError(f"k must lie in [1, {len(points)}], got {k}")
    if len(points) <= FEW_POINTS:
        return _k_nearest_grouped(points, queries, int(k), float(QUERIES_PER_GROUP))
    return _k_nearest(points, queries, int(k), float(PER_CELL))


def kth_distance(points: np.ndarray, queries: np.ndarray, k: int) -> np.ndarray:
    """(Q,) distance from each query to its k-th nearest point (a query among `points` counts itself):
    cKDTree(points).query(queries, k=[k])'s."""
    return k_nearest(points, queries, k)[0][:, -1]


__all__ = ["FEW_POINTS", "PER_CELL", "QUERIES_PER_GROUP", "k_nearest", "kth_distance", "nearest_indices"]
