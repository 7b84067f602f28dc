"""The ray from a scatter in front of the optics to a point behind them, through the glass between.

Why. Past the field most stray light scatters on a mechanical face y1 in front of (or between) lens
groups, refracts through the optics behind it and lands on a face y2 the detector sees straight; a
photon makes that y1 → y2 step rarely (the strip by the detector subtends a tiny solid angle through
the rear group), so a few photons carry a pass. Manifold next-event estimation (Hanika, Droske &
Fascione 2015) connects y1 to a chosen y2 instead: the specular chain between two points is found by
a root find, and the connection carries the chain's generalised geometric term.

What. In a coaxial system the chain's ray is fixed by where it crosses the plane of the first
surface's vertex, a point a = (a_x, a_y): the direction at y1 is a − y1. Tracing that ray through the
surfaces between (Snell's law on each analytic profile, the media's indices at the photon's
wavelength) and on to the plane z = y2_z gives a landing point X(a); the chain from y1 to y2 is the
root of X(a) − y2_xy, found by Newton's method with a central finite-difference Jacobian J = ∂X/∂a,
every photon at once. At the root

    |dω1/dA2| = (|ω1_z| / |a − y1|²) / |det J| · |d2 · n2| / |d2_z|

(solid angle at y1 per area of the aim plane, over the aim plane's area per landing plane's area,
times the landing plane's area per area of y2's face; d2 the chain's last direction, n2 the face's
normal). Without glass this is cos θ2 / |y1 − y2|², the ordinary geometric term's. Rays that leave a
surface's mechanical aperture, meet total internal reflection or do not converge are refused: the
found chain is a candidate whose visibility (metal on the way) and Fresnel / absorption throughput
the tracer decides.

The connection (`connections_through_optics`). At a photon's scatter y1 on a broad mechanical face in front
of an optical surface, y2 is drawn by area on the broad faces behind the last surface (`ViewCells`: a
triangle with probability ∝ area × its view of the detector), the chain solved and traced, and y2 handed
to the detector connection (`connect`) as a photon of flux Φ f(y1) cos θ1 |dω1/dA2| T / p_area(y2). The
walk's own photons that made the same step are the other technique for the same paths: each path is
shared by the balance heuristic on the two area densities at y2, p_area and p_walk = p_dir(ω1)·|dω1/dA2|
(p_dir the walk's density at y1, aimed or not; roulette left out of both, so the two weights add to 1 path
by path, `walk_share`). The walk's photon counts as "the same step" only where the solve from its y1 to its
y2 leaves along its own last direction, so a chain the solve would not find stays the walk's alone.
Off by default (`EstimatorSettings.connect_through_optics`; docs/bidirectional.md has the measurements).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.integrators.scatter_aim import AIMED_SHARE, ApertureTargets, disc_pdf
from lensmount.integrators.walk import Vertices
from lensmount.optics.snell import refract
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import Streams
from lensmount.trace.tracer import FACE

NEWTON_STEPS = 25
NEWTON_TOL = 1e-7  # mm on the landing plane
FD_STEP = 1e-5  # mm on the aim plane: the Jacobian's central differences


@dataclass(frozen=True)
class Chain:
    """The optical surfaces a ray crosses from z_from to z_to along +z, in order (scene.optical entries)."""

    surfaces: tuple

    @classmethod
    def between(cls, optical, z_from: float, z_to: float) -> "Chain":
        inside = [s for s in optical if z_from < s.z_vertex < z_to and not s.mirror]
        return cls(tuple(sorted(inside, key=lambda s: s.z_vertex)))

    @property
    def aim_z(self) -> float:
        return float(self.surfaces[0].z_vertex)


@dataclass
class ChainRays:
    """The solved chains of M connections.

    direction : (M, 3) unit direction at y1 toward the first surface
    exit_direction : (M, 3) unit direction after the last surface (toward y2)
    d_omega_d_area : (M,) |dω1/dA2| (1/mm²) per area of y2's face
    ok : (M,) converged, inside every surface's aperture, no total internal reflection, y2 ahead
    """

    direction: np.ndarray
    exit_direction: np.ndarray
    d_omega_d_area: np.ndarray
    ok: np.ndarray


def trace_chain(chain: Chain, origin: np.ndarray, direction: np.ndarray, wl: np.ndarray):
    """Trace rays (M,) from `origin` along `direction` through the chain's surfaces at wavelength index
    wl: (last point (M, 3), last direction (M, 3), passed (M,) bool: every surface met inside its
    mechanical aperture and no total internal reflection)."""
    p, d = origin.astype(np.float64).copy(), direction.astype(np.float64).copy()
    ok = np.ones(len(p), bool)
    for s in chain.surfaces:
        local = p - np.array([0.0, 0.0, s.z_vertex])
        t = s.profile.intersect(local, d)
        hit = np.isfinite(t) & (t > 0)
        t = np.where(hit, t, 0.0)
        q = local + t[:, None] * d
        rim = s.mechanical_semi_diameter if np.isfinite(s.mechanical_semi_diameter) else s.clear_semi_diameter
        hit &= (q[:, 0] ** 2 + q[:, 1] ** 2) <= rim * rim
        new_d, tir, _, _ = refract(d, s.profile.normal(q), s.n_before[wl] / s.n_after[wl])
        ok &= hit & ~tir
        p = np.where(ok[:, None], q + np.array([0.0, 0.0, s.z_vertex]), p)
        d = np.where(ok[:, None], new_d, d)
    return p, d, ok


def _landing(chain: Chain, y1: np.ndarray, aim: np.ndarray, z2: np.ndarray, wl: np.ndarray):
    """(M, 2) where the chain's ray through aim point `aim` (M, 2) crosses the plane z2, the ray's last
    direction, its direction at y1, and whether it got there."""
    to_a = np.column_stack([aim, np.full(len(aim), chain.aim_z)]) - y1
    w1 = to_a / np.linalg.norm(to_a, axis=1)[:, None]
    p, d, ok = trace_chain(chain, y1, w1, wl)
    ahead = d[:, 2] > 1e-9
    t = np.where(ahead, (z2 - p[:, 2]) / np.where(ahead, d[:, 2], 1.0), 0.0)
    ok &= ahead & (t >= 0)
    return p[:, :2] + t[:, None] * d[:, :2], d, w1, ok


def solve_chain(chain: Chain, y1: np.ndarray, y2: np.ndarray, normal2: np.ndarray, wl: np.ndarray,
                start: np.ndarray | None = None) -> ChainRays:
    """The chain's rays from points y1 (M, 3) to points y2 (M, 3) on faces of normal normal2 (M, 3),
    at wavelength index wl (M,) (module docstring). start (M, 2): the first guess on the aim plane
    (default: where the straight line y1 → y2 crosses it)."""
    m = len(y1)
    z2 = y2[:, 2]
    if start is None:
        s = (chain.aim_z - y1[:, 2]) / np.where(np.abs(y2[:, 2] - y1[:, 2]) > 1e-12, y2[:, 2] - y1[:, 2], 1e-12)
        start = y1[:, :2] + s[:, None] * (y2[:, :2] - y1[:, :2])
    a = start.astype(np.float64).copy()
    live = np.ones(m, bool)
    done = np.zeros(m, bool)
    for _ in range(NEWTON_STEPS):
        rows = np.flatnonzero(live & ~done)
        if not len(rows):
            break
        x, _, _, ok = _landing(chain, y1[rows], a[rows], z2[rows], wl[rows])
        r = x - y2[rows, :2]
        done[rows[ok & (np.hypot(r[:, 0], r[:, 1]) < NEWTON_TOL)]] = True
        live[rows[~ok]] = False
        step = ok & ~done[rows]  # the Jacobian only where a step is still to take (most chains fail at once)
        rows, r = rows[step], r[step]
        jac, jok = _jacobian(chain, y1[rows], a[rows], z2[rows], wl[rows])
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        good = jok & (np.abs(det) > 1e-300)
        live[rows[~good]] = False
        g = np.flatnonzero(good)
        inv = np.stack([np.stack([jac[g, 1, 1], -jac[g, 0, 1]], -1), np.stack([-jac[g, 1, 0], jac[g, 0, 0]], -1)], 1)
        a[rows[g]] -= _limited(np.einsum("nij,nj->ni", inv, r[g]) / det[g][:, None], chain)
    ok = done & live
    w1, d2, g = np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m)
    k = np.flatnonzero(ok)
    _, d2[k], w1[k], reached = _landing(chain, y1[k], a[k], z2[k], wl[k])
    jac, jok = _jacobian(chain, y1[k], a[k], z2[k], wl[k])
    det = np.abs(jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0])
    fine = reached & jok & (det > 0)
    ok[k] = fine
    k, det = k[fine], det[fine]
    to_a = np.column_stack([a[k], np.full(len(k), chain.aim_z)]) - y1[k]
    per_aim = np.abs(w1[k, 2]) / np.einsum("ij,ij->i", to_a, to_a)
    per_face = np.abs(np.einsum("ij,ij->i", d2[k], normal2[k])) / np.maximum(np.abs(d2[k, 2]), 1e-300)
    g[k] = per_aim / det * per_face
    return ChainRays(w1, d2, g, ok)


def _jacobian(chain, y1, a, z2, wl):
    """(M, 2, 2) ∂X/∂a by central differences, and where all four neighbours landed."""
    jac = np.zeros((len(a), 2, 2))
    ok = np.ones(len(a), bool)
    for k in range(2):
        e = np.zeros(2)
        e[k] = FD_STEP
        xp, _, _, okp = _landing(chain, y1, a + e, z2, wl)
        xm, _, _, okm = _landing(chain, y1, a - e, z2, wl)
        jac[:, :, k] = (xp - xm) / (2 * FD_STEP)
        ok &= okp & okm
    return jac, ok


def _limited(step: np.ndarray, chain: Chain) -> np.ndarray:
    """Newton steps no longer than a fifth of the first surface's aperture (keeps the aim on the glass)."""
    s = chain.surfaces[0]
    cap = 0.2 * (s.mechanical_semi_diameter if np.isfinite(s.mechanical_semi_diameter) else s.clear_semi_diameter)
    n = np.linalg.norm(step, axis=1)
    return step * np.minimum(1.0, cap / np.maximum(n, 1e-300))[:, None]




# ----------------------------------------------------------------------------- the connection

ARRIVAL_TOL = 1e-3  # mm: the tracer's ray along the found chain lands this close to y2, on its face


@dataclass(frozen=True)
class ViewCells:
    """Triangles of broad faces behind the optics that the detector sees straight, each picked with
    probability ∝ its area × its view of the detector (`of_scene`), a point uniform in it.

    prim (K,) triangle index; tag (K,); corner (K, 3, 3); normal (K, 3) toward the detector's side;
    area (K,) mm²; cdf (K,); pdf_of_prim (T,) the area density (1/mm²) of a point in each triangle
    of the mesh (0 outside the cells); z_behind: the plane behind every optical surface."""

    prim: np.ndarray
    tag: np.ndarray
    corner: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    cdf: np.ndarray
    pdf_of_prim: np.ndarray
    z_behind: float

    @classmethod
    def of_scene(cls, scene, broad: np.ndarray) -> "ViewCells | None":
        """None when no such face: no optics, a mirror, nothing broad behind the last surface."""
        optical = list(scene.optical)
        if not optical or any(s.mirror for s in optical):
            return None
        z_last = max(s.z_vertex + max(0.0, _rim_sag(s)) for s in optical)
        mesh, det = scene.mesh, scene.detector
        mechanical = np.all(np.asarray(scene.solid_index_of_tag) == 1.0, axis=1)
        corner = mesh.vertices[mesh.triangles]
        centre = corner.mean(axis=1)
        cross = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
        area = 0.5 * np.linalg.norm(cross, axis=1)
        normal = cross / np.maximum(2 * area, 1e-300)[:, None]
        view, side = np.zeros(len(area)), np.zeros(len(area))
        for px, py in ((0.0, 0.0), (-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)):
            # the view of the detector's centre and corners, from either side of the face
            to_d = np.array([px * det.width, py * det.height, det.z]) - centre
            d2 = np.einsum("ij,ij->i", to_d, to_d)
            cos_x = np.einsum("ij,ij->i", to_d, normal) / np.sqrt(d2)
            cos_d = np.maximum(to_d[:, 2] / np.sqrt(d2), 0.0)
            view += np.abs(cos_x) * cos_d / d2 * det.width * det.height / 5
            side += cos_x * cos_d
        tags = mesh.tags
        keep = (broad[tags] & mechanical[tags] & (centre[:, 2] > z_last) & (centre[:, 2] < det.z)
                & (view > 0) & (area > 0))
        if not keep.any():
            return None
        k = np.flatnonzero(keep)
        importance = area[k] * view[k]
        importance = np.maximum(importance, 1e-3 * importance.max() * area[k] / area[k].max())  # every cell reachable
        pick = importance / importance.sum()
        pdf_of_prim = np.zeros(len(area))
        pdf_of_prim[k] = pick / area[k]
        oriented = normal[k] * np.where(side[k] >= 0, 1.0, -1.0)[:, None]
        return cls(k, tags[k], corner[k], oriented, area[k], np.cumsum(pick), pdf_of_prim, float(z_last))

    def sample(self, u: np.ndarray):
        """Points (M, 3), their normals, tags, triangles and area densities from uniforms u (M, 3)."""
        i = np.minimum(np.searchsorted(self.cdf, u[:, 0] * self.cdf[-1], side="right"), len(self.cdf) - 1)
        s = np.sqrt(u[:, 1])
        b = np.column_stack([1 - s, s * (1 - u[:, 2]), s * u[:, 2]])
        y = np.einsum("nk,nkj->nj", b, self.corner[i])
        return y, self.normal[i], self.tag[i], self.prim[i], self.pdf_of_prim[self.prim[i]]


def _rim_sag(s) -> float:
    h = s.mechanical_semi_diameter if np.isfinite(s.mechanical_semi_diameter) else s.clear_semi_diameter
    sag = float(s.profile.sag(np.array([h * h]))[0]) if np.isfinite(h) else 0.0
    return sag if np.isfinite(sag) else 0.0


def photon_direction_pdf(scene, aim, tag, position, wi, normal, wo) -> np.ndarray:
    """(M,) the solid-angle density with which the walk draws wo at a scatter (tag, position) arriving
    from wi: the BSDF's, or where `aim` aims the mixture (`scatter_aim`)."""
    p = np.zeros(len(tag))
    for t in np.unique(tag):
        sel = np.flatnonzero(tag == t)
        p[sel] = np.asarray(scene.bsdf_of_tag[int(t)].pdf(wi[sel], wo[sel], normal[sel]), np.float64)
    if aim is not None:
        a = np.flatnonzero(aim.aimed(tag, position))
        if len(a):
            p[a] = (1 - AIMED_SHARE) * p[a] + AIMED_SHARE * disc_pdf(aim, aim.disc_of(position[a]), position[a], wo[a])
    return p


@dataclass(frozen=True)
class ThroughOptics:
    """What the connection through the optics needs for one scene: the cells, the walk's aim, the faces
    whose scatters start a connection (broad, the lobe the gather counts whole, mechanical) and the
    last optical surface's vertex (a start lies in front of it)."""

    cells: ViewCells
    aim: ApertureTargets | None
    whole: np.ndarray
    last_vertex: float

    @classmethod
    def of_scene(cls, scene, core: np.ndarray, scatters: np.ndarray, aim) -> "ThroughOptics | None":
        mechanical = np.all(np.asarray(scene.solid_index_of_tag) == 1.0, axis=1)
        whole = (np.asarray(core) == 0) & np.asarray(scatters, bool) & mechanical
        cells = ViewCells.of_scene(scene, np.isfinite(core) & np.asarray(scatters, bool))
        if cells is None or not whole.any():
            return None
        return cls(cells, aim, whole, float(max(s.z_vertex for s in scene.optical)))

    def starts(self, tag: np.ndarray, position: np.ndarray) -> np.ndarray:
        """(M,) scatters at (tag, position) that start a connection through the optics: an optical surface ahead."""
        return self.whole[tag] & (position[:, 2] < self.last_vertex)


def _chains(scene, z1: np.ndarray, z_to: float):
    """Groups of rows by the chain ahead of each z1 (the surfaces between z1 and z_to): (Chain, rows)."""
    zs = np.sort([s.z_vertex for s in scene.optical])
    ahead = np.searchsorted(zs, z1, side="right")
    for k in np.unique(ahead[ahead < len(zs)]):
        yield Chain.between(scene.optical, float(zs[k]) - 1e-9, z_to), np.flatnonzero(ahead == k)


def _solve(scene, y1, y2, n2, wl) -> ChainRays:
    """solve_chain by the chain ahead of each y1 (not ok where none)."""
    m = len(y1)
    out = ChainRays(np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m), np.zeros(m, bool))
    for chain, rows in _chains(scene, y1[:, 2], scene.detector.z):
        if not chain.surfaces:
            continue
        r = solve_chain(chain, y1[rows], y2[rows], n2[rows], wl[rows])
        out.direction[rows], out.exit_direction[rows] = r.direction, r.exit_direction
        out.d_omega_d_area[rows], out.ok[rows] = r.d_omega_d_area, r.ok
    return out


@dataclass
class Arrivals:
    """The connections that landed on y2: rows of the scatters they started from, position, direction
    (travel, after the optics), normal, flux Φ f1 cos θ1 |dω1/dA2| T / p_area · share, tag, prim, and share,
    the balance heuristic's weight p_area / (p_area + p_walk) included in flux."""

    rows: np.ndarray
    position: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    flux: np.ndarray
    tag: np.ndarray
    prim: np.ndarray
    share: np.ndarray


def connections_through_optics(scene, tracer, cells: ViewCells, aim, v: Vertices, bounce: int, seed: int,
                               purpose: str) -> Arrivals:
    """Virtual photons on the faces behind the optics (`ViewCells`), one per scatter y1 in `v` (each in
    front of an optical surface): y2 drawn by area, the chain y1 → y2 solved, traced by the tracer (metal
    on the way, Fresnel and absorption), weighted by the balance heuristic against the walk's own photons
    reaching y2 that way (`walk_share`), for the detector connection."""
    m = len(v.flux)
    u = Streams(seed, purpose + "/through-optics", v.id, step=int(bounce)).random((m, 3))
    y2, n2, tag2, prim2, p_area = cells.sample(u)
    chain = _solve(scene, v.position, y2, n2, v.wavelength)
    w1 = chain.direction
    cos1 = np.einsum("ij,ij->i", w1, v.normal)
    ok = chain.ok & (cos1 > 0) & (np.einsum("ij,ij->i", chain.exit_direction, n2) < 0)
    k = np.flatnonzero(ok)
    throughput = np.zeros(0)
    if len(k):
        seen = tracer.next_event(RayBatch.make(v.position[k], w1[k], np.ones(len(k)), v.wavelength[k], v.id[k]),
                                 None, v.normal[k])
        landed = ((seen.kind == FACE) & (seen.tag == tag2[k])
                  & (np.linalg.norm(seen.position - y2[k], axis=1) < ARRIVAL_TOL) & (seen.weight > 0))
        k, throughput = k[landed], seen.weight[landed]
    f1 = np.zeros(len(k))
    for t in np.unique(v.tag[k]):
        rows = np.flatnonzero(v.tag[k] == t)
        f1[rows] = np.asarray(scene.bsdf_of_tag[int(t)].eval(v.wi[k][rows], w1[k][rows], v.normal[k][rows]), np.float64)
    g = chain.d_omega_d_area[k]
    p_walk = photon_direction_pdf(scene, aim, v.tag[k], v.position[k], v.wi[k], v.normal[k], w1[k]) * g
    share = p_area[k] / (p_area[k] + p_walk)
    flux = v.flux[k] * np.maximum(f1, 0.0) * cos1[k] * g * throughput / p_area[k] * share
    return Arrivals(k, y2[k], chain.exit_direction[k], n2[k], flux, tag2[k], prim2[k], share)


def walk_share(scene, cells: ViewCells, aim, came_from: Vertices, arrival_position, arrival_direction,
               arrival_normal, arrival_prim) -> np.ndarray:
    """(M,) the balance heuristic's weight of photons that scattered at `came_from` (y1) and reached y2
    (arrival_*) with nothing but the optics between: p_walk / (p_walk + p_area) where the connection
    would have found the same chain (the solve from y1 to y2 leaves along the photon's own last
    direction), 1 elsewhere."""
    share = np.ones(len(arrival_position))
    p_area = cells.pdf_of_prim[arrival_prim]
    k = np.flatnonzero(p_area > 0)
    if not len(k):
        return share
    chain = _solve(scene, came_from.position[k], arrival_position[k], arrival_normal[k], came_from.wavelength[k])
    same = chain.ok & (np.einsum("ij,ij->i", chain.exit_direction, arrival_direction[k]) > 1 - 1e-9)
    k, w1, g = k[same], chain.direction[same], chain.d_omega_d_area[same]
    p_walk = photon_direction_pdf(scene, aim, came_from.tag[k], came_from.position[k], came_from.wi[k],
                                  came_from.normal[k], w1) * g
    share[k] = p_walk / (p_walk + p_area[k])
    return share


__all__ = ["Arrivals", "Chain", "ChainRays", "ThroughOptics", "Vertices", "ViewCells", "connections_through_optics",
           "photon_direction_pdf", "solve_chain", "trace_chain", "walk_share"]
