"""Gather radii: the pass's common shrink factor s_i and each hit point's starting radius r_0.

Knaus & Zwicker (2011): with independent passes, the radius of pass i is
r_i(y) = r_0(y) · s_i with

    s_1 = 1,   s_{i+1}² = s_i² · (i + α) / (i + 1),   0 < α < 1  (α = 0.7 default)

so s_i² ~ i^(α−1) → 0 (the bias vanishes) while Σ 1/(photons in r_i) still grows
slowly enough that the mean of the passes converges. The closed form via log-gamma
keeps pass 10 000 as exact as pass 2.

r_0(y) is the hit point's own footprint — the distance to its k-th nearest
neighbour among the pass's hit points on the same CAD face — capped by the face's
width (2 · area / boundary length), or for strips by a few mm along them (`radius_caps`).

Boundary correction (`FaceBoundaries.inside_area`): the density estimate divides by
the area of the gather disc that lies ON the face, not by π r². Near a face boundary
(always, on the 50 µm diaphragm edge) π r² would count area where no photon of this
face can land and bias the edge's light low by ~20 %. The boundary near a hit point
is taken as the two straight lines through the nearest boundary segment and the
nearest one on the opposite side (a strip: exact; a disc's rim or an annulus: exact
to O(r/R)); each cuts a circular cap off the disc.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lensmount.integrators.photon_mapping.neighbours import kth_distance, nearest_indices
from lensmount.integrators.settings import EstimatorSettings

DEFAULT_ALPHA = 0.7


def radius_scale(pass_index: int, alpha: float = DEFAULT_ALPHA) -> float:
    """s_i for 0-based pass_index (pass i = pass_index + 1): s² = Γ(i+α)Γ(2) / (Γ(1+α)Γ(i+1))."""
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    i = int(pass_index) + 1
    log_s2 = math.lgamma(i + alpha) - math.lgamma(1.0 + alpha) - math.lgamma(i + 1.0) + math.lgamma(2.0)
    return math.exp(0.5 * log_s2)


def face_half_widths(vertices: np.ndarray, triangles: np.ndarray, tags: np.ndarray, n_tags: int) -> np.ndarray:
    """(n_tags,) half width of every tagged face: area / boundary length (mm); inf for no triangles.

    A strip of width w and length L ≫ w (the diaphragm edge) gives w/2; a disc of
    radius R gives R/2. The boundary is the set of edges used by one triangle of the tag.
    """
    tri = np.asarray(triangles, dtype=np.int64)
    v = np.asarray(vertices, dtype=np.float64)
    tags = np.asarray(tags)
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    area_of = np.bincount(tags, weights=area, minlength=n_tags)[:n_tags]
    # Edges keyed by (tag, min vertex, max vertex); a boundary edge occurs once within its tag.
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    et = np.concatenate([tags, tags, tags]).astype(np.int64)
    e.sort(axis=1)
    uniq, counts = np.unique(_edge_keys(et, e, len(v)), return_counts=True)
    boundary = uniq[counts == 1]
    tag_of, (i, j) = boundary // (len(v) * len(v)), np.divmod(boundary % (len(v) * len(v)), len(v))
    length = np.linalg.norm(v[i] - v[j], axis=1)
    perim = np.bincount(tag_of, weights=length, minlength=n_tags)[:n_tags]
    out = np.full(n_tags, np.inf)
    ok = (perim > 0) & (area_of > 0)
    out[ok] = area_of[ok] / perim[ok]
    return out


def _edge_keys(tag: np.ndarray, ends: np.ndarray, n_vertices: int) -> np.ndarray:
    """One int64 per edge of a tag, (tag, low vertex, high vertex) in lexicographic order: np.unique
    over it is np.unique(axis=0) over the triples, many times faster (rows are sorted as structs)."""
    n = np.int64(max(int(n_vertices), 1))
    if (int(tag.max(initial=0)) + 1) * int(n) * int(n) >= 2**63:
        raise ValueError(f"{n_vertices} vertices: edge keys overflow int64")
    return (tag.astype(np.int64) * n + ends[:, 0]) * n + ends[:, 1]


def face_bends(vertices, triangles, tags, n_tags: int) -> tuple[np.ndarray, np.ndarray]:
    """(n_tags,) smallest radius of curvature of every tagged face (mm; inf for a flat face) and
    (n_tags,) largest angle between the normals of two neighbouring triangles (radians).

    From each pair of triangles of one tag that share an edge of length L: the normals turn
    by θ across the mean of the two triangles' heights over that edge, h = 2·area / L, so
    R = (area₁ + area₂) / (L θ). A tessellated cylinder of radius R gives R; a plane, inf."""
    v = np.asarray(vertices, np.float64)
    tri = np.asarray(triangles, np.int64)
    tags = np.asarray(tags, np.int64)
    out, turn = np.full(n_tags, np.inf), np.zeros(n_tags)
    if len(tri) == 0:
        return out, turn
    welded = _weld(v, tri)
    cross = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    nrm = cross / np.maximum(2.0 * area, 1e-300)[:, None]
    e = np.sort(np.concatenate([welded[:, [0, 1]], welded[:, [1, 2]], welded[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(len(tri)), 3)
    ends = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    keys = np.stack([tags[owner], e[:, 0], e[:, 1]], axis=1)
    order = np.lexsort(keys.T[::-1])
    k = keys[order]
    pair = np.flatnonzero(np.all(k[1:] == k[:-1], axis=1))  # consecutive equal keys: two triangles, one edge
    if len(pair) == 0:
        return out, turn
    t1, t2 = owner[order[pair]], owner[order[pair + 1]]
    edge = ends[order[pair]]
    length = np.linalg.norm(v[edge[:, 1]] - v[edge[:, 0]], axis=1)
    angle = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", nrm[t1], nrm[t2])), -1.0, 1.0))
    bent = (angle > 1e-6) & (length > 0)
    radius = np.where(bent, (area[t1] + area[t2]) / np.where(bent, length * angle, 1.0), np.inf)
    np.minimum.at(out, k[pair, 0], radius)
    np.maximum.at(turn, k[pair, 0], angle)
    return out, turn


def radius_caps(vertices, triangles, tags, n_tags: int, cap_mm: float = 5.0, strip_ratio: float = 0.05,
                max_normal_deg: float = EstimatorSettings.normal_limit_deg) -> np.ndarray:
    """(n_tags,) largest r_0 per face.

    A compact face (half width ≥ strip_ratio × its extent: plates, annuli of some width)
    caps r_0 at its full width 2·hw. A strip (the 50 µm diaphragm edge, a lens rim, a bevel:
    half width ≪ extent) allows r_0 up to cap_mm ALONG the strip: its boundary near any hit
    point is two parallel lines, so `FaceBoundaries.inside_area` gives the on-face area of a
    large disc exactly (≈ 2 r w) and the gather collects the edge's photons over millimetres
    of its length instead of a 25 µm disc.

    On a curved face the gather keeps only photons whose facet normal is within max_normal_deg
    of the hit point's (`photon_gather.Gatherer`), while the on-face area counts the whole disc.
    So r is also capped at the chord 2 R sin(β / 2) of the face's tightest bend R, with
    β = max_normal_deg − the largest turn between neighbouring facets (facet normals are
    quantised by that much): every photon of the face inside the disc then passes the normal
    test, and the area counts only the band whose photons are kept. A 50 µm edge of R = 2 mm
    read 0.21 of the truth at r = 5 mm (`tests/physics/test_thin_edge_uniform_light.py`).
    """
    bend, turn = face_bends(vertices, triangles, tags, n_tags)
    beta = np.maximum(math.radians(max_normal_deg) - turn, 0.25 * math.radians(max_normal_deg))
    chord = 2.0 * bend * np.sin(beta / 2.0)
    hw = face_half_widths(vertices, triangles, tags, n_tags)
    v = np.asarray(vertices, np.float64)[np.asarray(triangles, np.int64)].reshape(-1, 3)
    t3 = np.repeat(np.asarray(tags, np.int64), 3)
    lo = np.full((n_tags, 3), np.inf)
    hi = np.full((n_tags, 3), -np.inf)
    np.minimum.at(lo, t3, v)
    np.maximum.at(hi, t3, v)
    extent = np.where(np.isfinite(lo).all(axis=1), np.linalg.norm(hi - lo, axis=1), 0.0)
    strip = np.isfinite(hw) & (hw < strip_ratio * extent)
    return np.minimum(np.where(strip, cap_mm, np.minimum(2.0 * hw, cap_mm)), chord)


def _weld(vertices: np.ndarray, triangles: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """Triangles re-indexed so coincident vertices (within tol mm) share an index."""
    key = np.round(np.asarray(vertices, np.float64) / tol).astype(np.int64)
    _, inverse = np.unique(key, axis=0, return_inverse=True)
    return inverse.reshape(-1)[np.asarray(triangles, np.int64)]


def boundary_segments(vertices, triangles, tags, with_inward: bool = False):
    """Boundary edges of every tagged face: (a (B, 3), b (B, 3), tag (B,)[, inward (B, 3)]).

    An edge is on the boundary when exactly one triangle of its own tag uses it (after
    welding coincident vertices, so a triangle soup still has interior edges). `inward`
    is the unit vector in that triangle's plane, perpendicular to the edge, into the face."""
    v = np.asarray(vertices, np.float64)
    tri = np.asarray(triangles, np.int64)
    welded = _weld(v, tri)
    e_w = np.concatenate([welded[:, [0, 1]], welded[:, [1, 2]], welded[:, [2, 0]]])
    e_v = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    third = np.concatenate([tri[:, 2], tri[:, 0], tri[:, 1]])
    et = np.concatenate([tags, tags, tags]).astype(np.int64)
    e_w = np.sort(e_w, axis=1)
    _, inverse, counts = np.unique(_edge_keys(et, e_w, len(v)), return_inverse=True, return_counts=True)
    once = counts[inverse.reshape(-1)] == 1
    a, b = v[e_v[once, 0]], v[e_v[once, 1]]
    if not with_inward:
        return a, b, et[once]
    ab = b - a
    ac = v[third[once]] - a
    inward = ac - (np.einsum("ij,ij->i", ac, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300))[:, None] * ab
    inward /= np.maximum(np.linalg.norm(inward, axis=1, keepdims=True), 1e-300)
    return a, b, et[once], inward


class FaceBoundaries:
    """Boundary segments of every face, indexed by tag, for the on-face gather area."""

    def __init__(self, vertices, triangles, tags, n_tags: int, k: int = 24):
        a, b, t, inward = boundary_segments(vertices, triangles, tags, with_inward=True)
        hw = face_half_widths(vertices, triangles, tags, n_tags)
        self.half_width = {int(k): float(hw[k]) for k in range(n_tags) if np.isfinite(hw[k])}
        self.k = k
        self.by_tag: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        for tag in np.unique(t):
            m = t == tag
            aa, bb = a[m], b[m]
            self.by_tag[int(tag)] = (aa, bb, inward[m], 0.5 * (aa + bb))

    def inside_area(self, position: np.ndarray, normal: np.ndarray, tag: np.ndarray, radius: np.ndarray,
                    detector_z: float | None = None) -> np.ndarray:
        """(H,) area of the disc (centre, radius, in the plane normal to `normal`) that lies on the face.

        The nearest boundary segment says, by its inward direction, whether the centre is on
        the face (the usual case) or a few µm off it (float32 grazing hits on a thin face).
        On the face: π r² minus the caps beyond the nearest boundary and the nearest one on
        the opposite side. Off it: the band between the nearest boundary and the far one.

        detector_z : the detector plane. The detector sees only z < detector_z, so the gather
            drops photons beyond it (`Gatherer`) and the area ends there too: the plane's line
            in the tangent plane is one more boundary, merged with the face boundary on its side.
            Without it a face crossing the plane (the housing bore, where the sun's image lands
            just behind the detector) lent the light the detector cannot see to the points it can.
        """
        return self.inside_areas(position, normal, tag, (radius,), detector_z)[0]

    def inside_areas(self, position: np.ndarray, normal: np.ndarray, tag: np.ndarray, radii,
                     detector_z: float | None = None) -> list[np.ndarray]:
        """`inside_area` for several radii (H,) each of the same hit points (the pass's ladder of radii):
        the boundaries near each point are found once, the caps cut for every radius (`_disc_areas`)."""
        radii = np.stack([np.asarray(r, np.float64) for r in radii])
        areas = np.pi * radii**2
        plane = detector_z is not None
        # Face by face, each face's hit points gathered once into consecutive rows (ascending, as a
        # mask would pick them).
        order = np.argsort(tag, kind="stable")
        faces, first = np.unique(tag[order], return_index=True)
        position, normal, radii = position[order], normal[order], radii[:, order]
        by_face = areas[:, order]
        for t, start, end in zip(faces, first, (*first[1:], len(order))):
            if int(t) not in self.by_tag:
                continue
            a, b, inward, middle = self.by_tag[int(t)]
            p, n = position[start:end], normal[start:end]
            cand = nearest_indices(middle, p, min(self.k, len(a)))
            hw = self.half_width.get(int(t), np.inf)
            d1, u1, d2, far, on_face = _nearest_boundaries(p, n, cand, a, b, inward, hw)
            by_face[:, start:end] = _disc_areas(p, n, d1, u1, d2, far, on_face,
                                                np.ascontiguousarray(radii[:, start:end]),
                                                float(detector_z) if plane else 0.0, plane)
        areas[:, order] = by_face
        return list(areas)


@njit(cache=True, inline="always")
def _dot(ax, ay, az, bx, by, bz):
    """a · b summed as numpy's einsum sums three terms here (two SIMD lanes: x and z, then y), so the
    compiled area is the numpy one to the bit."""
    return (ax * bx + az * bz) + ay * by


@njit(cache=True)
def _nearest_boundaries(p, nrm, cand, a, b, inward, hw):
    """For hit points p (H, 3) with face normals nrm and k candidate boundary segments each (cand (H, k),
    into a, b, inward): (d1 (H,) the distance in the tangent plane to the nearest segment, u1 (H, 3) the
    unit vector toward it, d2 (H,) the distance to the nearest one on the other side of the centre (inf:
    none), far (H,) off the face: the far boundary (inf: none), on_face (H,) bool).

    Compiled: one loop over the H × k candidates instead of ~20 (H, k, 3) temporaries (the view map's
    largest cost on a face-rich scene, ~3 s a call for 3 × 10⁵ hit points). Each number is computed as
    the numpy formulas did it, in the same order. Segments farther than d1 + hw (the face's half width)
    and not beyond the centre make the far boundary; nearer ones are the near boundary's own neighbours.
    """
    h_n, k_n = cand.shape
    d1 = np.empty(h_n)
    u1 = np.empty((h_n, 3))
    d2 = np.empty(h_n)
    far = np.empty(h_n)
    on_face = np.empty(h_n, np.bool_)
    v = np.empty((k_n, 3))
    d = np.empty(k_n)
    for h in range(h_n):
        px, py, pz = p[h, 0], p[h, 1], p[h, 2]
        nx, ny, nz = nrm[h, 0], nrm[h, 1], nrm[h, 2]
        near = 0
        for j in range(k_n):
            c = cand[h, j]
            ax, ay, az = a[c, 0], a[c, 1], a[c, 2]
            ex, ey, ez = b[c, 0] - ax, b[c, 1] - ay, b[c, 2] - az
            s = _dot(px - ax, py - ay, pz - az, ex, ey, ez) / max(_dot(ex, ey, ez, ex, ey, ez), 1e-300)
            s = min(max(s, 0.0), 1.0)
            vx, vy, vz = ax + s * ex - px, ay + s * ey - py, az + s * ez - pz
            vn = _dot(vx, vy, vz, nx, ny, nz)
            vx, vy, vz = vx - vn * nx, vy - vn * ny, vz - vn * nz  # in the tangent plane
            v[j, 0], v[j, 1], v[j, 2] = vx, vy, vz
            d[j] = math.sqrt(vx * vx + vy * vy + vz * vz)
            if d[j] < d[near]:
                near = j
        dn = d[near]
        d1[h] = dn
        ux, uy, uz = v[near, 0] / max(dn, 1e-300), v[near, 1] / max(dn, 1e-300), v[near, 2] / max(dn, 1e-300)
        u1[h, 0], u1[h, 1], u1[h, 2] = ux, uy, uz
        c = cand[h, near]
        on_face[h] = _dot(-v[near, 0], -v[near, 1], -v[near, 2], inward[c, 0], inward[c, 1], inward[c, 2]) >= 0.0
        best_beyond, best_far = np.inf, np.inf
        for j in range(k_n):
            if _dot(v[j, 0], v[j, 1], v[j, 2], ux, uy, uz) < 0:  # on the other side of the centre
                best_beyond = min(best_beyond, d[j])
            elif d[j] > dn + hw:
                best_far = min(best_far, d[j])
        d2[h] = best_beyond
        far[h] = best_far
    return d1, u1, d2, far, on_face


@njit(cache=True, inline="always")
def _cap(d, r):
    """Area of the part of a disc of radius r beyond a line at distance d from its centre."""
    x = min(max(d / max(r, 1e-300), 0.0), 1.0)
    return r * r * (math.acos(x) - x * math.sqrt(max(1.0 - x * x, 0.0)))


@njit(cache=True)
def _disc_areas(p, nrm, d1, u1, d2, far, on_face, radii, detector_z, plane):
    """(R, H) the on-face area of each hit point's disc of every radius radii (R, H), from its boundaries
    (`_nearest_boundaries`: d1, u1, d2, far, on_face); `plane`: the detector plane z = detector_z is one
    more boundary (`FaceBoundaries.inside_area`).

    On the face: π r² minus the caps beyond the nearest boundary and the nearest one on the other side,
    the plane's line merged into whichever side it lies on (nearer wins). Off it: the band from the
    nearest boundary to the far one. Floored against rounding only: a point on a strip of width w keeps
    at least min(π r²/2, r w) of its disc; half of that is never above the true area.

    Compiled (the view map's largest numpy cost after the boundary search, ~0.45 s a case-2 pass): every
    number as the numpy formulas computed it, in the same order (π r r is (π r) r; the plane's slope
    |g| sums g_x² + g_y² first, as numpy's norm does), so each area is the same float."""
    r_n, h_n = radii.shape
    out = np.empty((r_n, h_n))
    for h in range(h_n):
        near_cut, far_cut = d1[h], d2[h]
        if plane:
            # The plane z = detector_z cuts the tangent plane in a line at distance (detector_z − z) / |g|
            # along g, the tangent direction of steepest z ascent (none when the face is parallel to it).
            nx, ny, nz = nrm[h, 0], nrm[h, 1], nrm[h, 2]
            gx, gy, gz = 0.0 - nz * nx, 0.0 - nz * ny, 1.0 - nz * nz
            slope = math.sqrt((gx * gx + gy * gy) + gz * gz)
            if slope > 1e-9:
                dist = max((detector_z - p[h, 2]) / slope, 0.0)
                if _dot(gx, gy, gz, u1[h, 0], u1[h, 1], u1[h, 2]) > 0:
                    near_cut = min(near_cut, dist)
                else:
                    far_cut = min(far_cut, dist)
        for i in range(r_n):
            r = radii[i, h]
            d2r = far_cut if math.isfinite(far_cut) else r  # a cap at distance >= r is empty
            far_r = far[h] if math.isfinite(far[h]) else r
            if on_face[h]:
                inside = math.pi * r * r - _cap(near_cut, r) - _cap(d2r, r)
                width = near_cut + d2r
            else:  # off the face: the face is the band from the nearest boundary to the far one
                inside = _cap(d1[h], r) - _cap(far_r, r)
                width = far[h] - d1[h] if math.isfinite(far[h]) else r
            floor = 0.5 * min(0.5 * math.pi * r * r, r * width)
            out[i, h] = max(inside, max(floor, 1e-12 * math.pi * r * r))
    return out


def initial_radii(position: np.ndarray, tag: np.ndarray, cap: np.ndarray, k: int = 8,
                  floor_mm: float = 1e-4, cap_mm: float = 5.0) -> np.ndarray:
    """(H,) r_0 per hit point: k-th neighbour distance on the same face, clipped to
    [floor_mm, min(cap_mm, cap[tag])] (`radius_caps`). Loops over faces (tags), not over points."""
    position = np.asarray(position, dtype=np.float64).reshape(-1, 3)
    tag = np.asarray(tag)
    order = np.argsort(tag, kind="stable")  # each face's points in consecutive rows, ascending
    faces, first = np.unique(tag[order], return_index=True)
    on_face = position[order]
    r = np.full(len(position), cap_mm)
    for t, start, end in zip(faces, first, (*first[1:], len(order))):
        if end - start > 1:
            kk = min(k, end - start - 1)
            p = on_face[start:end]
            r[start:end] = kth_distance(p, p, kk + 1)  # the point itself is the first
        limit = min(cap_mm, float(cap[t]) if t < len(cap) else cap_mm)
        r[start:end] = np.clip(r[start:end], min(floor_mm, limit), limit)
    out = np.empty_like(r)
    out[order] = r
    return out


__all__ = ["DEFAULT_ALPHA", "face_bends", "radius_scale", "face_half_widths", "radius_caps", "initial_radii", "FaceBoundaries", "boundary_segments"]
