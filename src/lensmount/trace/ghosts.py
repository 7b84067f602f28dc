"""Ghost paths traced deterministically: every route of Fresnel reflections between optical surfaces.

A route is the ordered list of surfaces where the light reflects. The classic two-reflection ghost
(j, i), j > i, crosses surfaces 1 … j, reflects at j, goes back through j−1 … i+1, reflects at i and
crosses i+1 … S to the detector. An odd number of reflections sends the light back out of the front,
so the next routes that reach the detector have four reflections (j, i, l, k); `max_reflections`
= 2 or 4 (ghost order 2 or 3, `reflections_of_order`).

How: a bundle of rays (a lattice over the first surface × the scene's wavelengths, `launch`) walks the
surfaces in sequence; at every surface that can reflect, the walk branches: the transmitted bundle
carries T = 1 − R, the reflected one R, with R the real unpolarised Fresnel or coating reflectance
(R_s + R_p)/2 per ray and wavelength, the quantity the tracer's reflection branch draws against.
Branches share their prefix, so the S³/6 two-reflection routes cost about S³/6 surface crossings
instead of S³/2 route by route. A mirror reflects every ray (weight R, not a Fresnel reflection;
R(1 − a) where its coated face scatters with a finish of albedo a, whose share the photons carry).
With `effects.absorption` the glass absorbs exp(-a L) along every step, as in the tracer.

Total internal reflection: the tracer reflects the ray without counting a Fresnel reflection, so
the route does the same: the ray turns back with its whole flux and the route's reflections
unchanged (at most MAX_TIR times a branch, as the tracer ends a ray trapped by it). A photon with
the route's reflection count and any number of total reflections is the route's.

Walls (`Walls`): the routes see the lens as the tracer does, through the scene's mesh. A surface
the mesh has no facets for (the stop plane in air) is no interface: the ray goes straight on. A
faceted surface is one whatever its media (a dummy surface with a coating reflects R, as in the
tracer). The glass of each surface ends where its faceted face ends: the outer rim of its
triangles seen along the axis (`GlassRim`), not `mechanical_semi_diameter` (when lens.toml omits
it that is the clear semi-diameter, while the mesh's glass reaches 1.5–9 mm further: the routes
lost 0.5–1.1 % of the double Gauss's two-reflection light, which the photons leave to them).
Without walls, a dummy surface is no interface and its clear aperture clips (the stop), and every
surface clips at its clear semi-diameter (the lens as the prescription describes it).

Walls (`Walls`): given the scene's tracer, every straight segment of a route is checked against the
mount's mechanical faces with the tracer's own exact query (`MechanicalFaces.occluded`, then
`nearest`), the first one from the source's emission plane, so hoods, vanes, spacers and the
diaphragm vignette ghost light where they vignette photons.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from lensmount.optics.snell import reflect, refract
from lensmount.physics.interfaces import facing, mirror_reflectance, reflectance
from lensmount.physics.sources import disc_radius_fraction, orthonormal_basis
from lensmount.scene.scene import scattering_mirror_tags

_R2 = (0.7548776662466927, 0.5698402909980532)  # the R2 sequence's generators (plastic number)
CENTRED = (0.0, 0.0, 0.5, 0.5)  # lattice through the axis, R2 sequence from its usual start: the report's
MAX_TIR = 8  # total internal reflections a branch follows; beyond, a ray circles a rim (the tracer ends it too)


def reflections_of_order(order: int) -> int:
    """Most Fresnel reflections traced for ghost order 2 (two) or 3 (four: three go back out the front)."""
    return 2 * (int(order) - 1)


@dataclass
class Launch:
    """Rays entering the lens: origins, directions (N, 3), flux (N,) E_sun·mm², wavelength (N,) index,
    positions: lattice points per wavelength (N = positions × W), spacing_mm: the lattice pitch."""

    origins: np.ndarray
    directions: np.ndarray
    flux: np.ndarray
    wavelength: np.ndarray
    positions: int
    spacing_mm: float


@dataclass
class Arrival:
    """The rays of one route on the detector plane. route: 1-based surfaces where it reflects, in order;
    points, directions (n, 3); flux (n,) E_sun·mm²; wavelength (n,) index into the scene's wavelengths."""

    route: tuple[int, ...]
    points: np.ndarray
    directions: np.ndarray
    flux: np.ndarray
    wavelength: np.ndarray


def route_count(reflects: np.ndarray, reflections: int) -> int:
    """How many routes of exactly `reflections` Fresnel reflections the surfaces `reflects` (S,) bool
    allow: reflect at j1, then at i1 < j1 on the way back, at j2 > i1 on the way forward, …"""
    ways = np.where(reflects, 1, 0).astype(np.int64)  # routes ending with a reflection at each surface
    idx = np.arange(len(reflects))
    for k in range(1, int(reflections)):
        backward = k % 2 == 1  # after an odd count the light travels back: the next surface is lower
        reach = idx[:, None] < idx[None, :] if backward else idx[:, None] > idx[None, :]
        ways = np.where(reflects, (reach * ways[None, :]).sum(axis=1), 0)
    return int(ways.sum())


def reflecting(scene) -> np.ndarray:
    """(S,) bool per optical surface (sequence order): can it make a ghost? Not perfect AR nor R = 0,
    not a dummy surface with the same medium on both sides, not a mirror (which reflects everything)."""
    out = []
    for s in scene.optical:
        c = s.coating
        dark = c.kind == "perfect-ar" or (c.kind == "constant" and c.reflectance == 0.0)
        out.append(not (dark or s.mirror or np.array_equal(s.n_before, s.n_after)))
    return np.array(out, bool)


def launch(scene, rays_across: int, shift=CENTRED, walls: Walls | None = None) -> Launch:
    """A square lattice across the beam (pitch: the first surface's aperture over rays_across) × wavelengths.

    The lattice lies in the plane normal to the source's direction through the middle of the first
    surface's cap, over the disc that holds the cap's shadow at any angle (its bounding sphere), so
    an oblique or grazing beam costs no more rays than a normal one. shift (4,) in [0, 1): lattice
    offset in pitches (2) and R2-sequence offset (2) of the sun's directions. A uniformly random
    shift makes the sum an unbiased estimate of the flux (randomised quasi-Monte Carlo), so
    independent shifts give independent passes and an honest error bar. Each ray carries
    pitch² · (d · d0) · p_λ (the irradiance crossing that plane, times the source's spectral share).
    walls: start on the source's emission plane (so the mount in front of the lens can block) over the
    first surface's faceted face, else just outside the cap over its clear aperture. A source behind the
    entrance plane (d0_z ≤ 0) launches nothing.
    """
    first = min(scene.optical, key=lambda s: s.index)
    radius = float(first.clear_semi_diameter) if walls is None else walls.reach(first)
    source = scene.source
    d0 = np.asarray(source.direction, np.float64)
    n_wl = len(scene.wavelengths_um)
    h = 2.0 * radius / max(int(rays_across) - 1, 1)
    if d0[2] <= 0.0:
        return Launch(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64), 0, h)
    sag = first.profile.sag(np.array([0.0, radius * radius]))
    z_lo, z_hi = first.z_vertex + min(float(sag.min()), 0.0), first.z_vertex + max(float(sag.max()), 0.0)
    centre = np.array([0.0, 0.0, 0.5 * (z_lo + z_hi)])
    bound = math.hypot(radius, 0.5 * (z_hi - z_lo))  # the cap's bounding sphere about `centre`
    reach = bound * (1.0 + math.tan(source.half_angle_rad)) + h
    m = int(math.ceil(reach / h)) + 1
    g = (np.arange(-m, m + 1) + shift[0]) * h, (np.arange(-m, m + 1) + shift[1]) * h
    x, y = np.meshgrid(*g)
    keep = x * x + y * y <= reach * reach
    x, y = x[keep], y[keep]
    n = len(x)
    e1, e2 = orthonormal_basis(d0)
    p = centre + x[:, None] * e1 + y[:, None] * e2
    directions = _directions(source, d0, n, shift[2:])
    along = directions @ d0
    if walls:  # back along each ray to the emission plane (through the disc's centre, normal to d0)
        back = ((p - np.asarray(source.disc.centre)) @ d0) / along
    else:
        back = np.full(n, bound + 1.0)
    origins = p - back[:, None] * directions
    weights = np.asarray(source.wavelength_weights, np.float64)
    share = weights / weights.sum() if len(weights) == n_wl and weights.sum() > 0 else np.full(n_wl, 1.0 / n_wl)
    flux = np.concatenate([h * h * along * s for s in share])
    return Launch(np.tile(origins, (n_wl, 1)), np.tile(directions, (n_wl, 1)), flux,
                  np.repeat(np.arange(n_wl), n), n, h)


def _directions(source, d0: np.ndarray, n: int, shift) -> np.ndarray:
    """n directions over the source's angular disc (shifted R2 sequence, the source's brightness law)."""
    alpha = float(source.half_angle_rad)
    if alpha <= 0.0:
        return np.tile(d0, (n, 1))
    k = np.arange(1, n + 1)
    u1, u2 = (shift[0] + _R2[0] * k) % 1.0, (shift[1] + _R2[1] * k) % 1.0
    rho = alpha * disc_radius_fraction(u1, source.limb_darkening)
    psi = 2.0 * math.pi * u2
    e1, e2 = orthonormal_basis(d0)
    d = (np.cos(rho)[:, None] * d0 + (np.sin(rho) * np.cos(psi))[:, None] * e1
         + (np.sin(rho) * np.sin(psi))[:, None] * e2)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@dataclass
class _Bundle:
    o: np.ndarray
    d: np.ndarray
    w: np.ndarray
    wl: np.ndarray
    on_glass: np.ndarray  # (n,) bool: the ray starts on glass (metal touching it is met at t = 0)


def trace_routes(scene, rays: Launch, max_reflections: int = 2, walls=None) -> Iterator[Arrival]:
    """Every route with an even number 2 … max_reflections of Fresnel reflections (see the module
    docstring) that brings light to the detector plane, as an `Arrival` (rays with flux > 0 only).

    walls : `Walls(tracer)` (the mount blocks) or None (clear apertures only).
    """
    surfaces = sorted(scene.optical, key=lambda s: s.index)
    ctx = _Context(scene, surfaces, reflecting(scene), walls, max_reflections)
    start = _Bundle(rays.origins, rays.directions, rays.flux.copy(), rays.wavelength, np.zeros(len(rays.flux), bool))
    yield from ctx.walk(_alive(start), -1, 1, ())


class _Context:
    def __init__(self, scene, surfaces, reflects, walls, max_reflections):
        self.scene, self.surfaces, self.reflects, self.walls = scene, surfaces, reflects, walls
        self.max_reflections = int(max_reflections)
        self.lam = np.asarray(scene.wavelengths_um, np.float64)
        self.dummy = [np.array_equal(s.n_before, s.n_after) and not s.mirror for s in surfaces]
        if walls is not None:  # the tracer's interfaces: the faceted surfaces, a coated dummy one too
            self.dummy = [walls.rims.get(s.index) is None for s in surfaces]
            self.reflects = np.array([r or (walls.rims.get(s.index) is not None and not s.mirror
                                            and s.coating.kind != "perfect-ar")
                                      for r, s in zip(reflects, surfaces)], bool)
        self.mirror_finish = {i: scene.bsdf_of_tag[t].finish for i, t in scattering_mirror_tags(scene).items()}

    def _specular_share(self, s, d: np.ndarray, nrm: np.ndarray) -> np.ndarray | float:
        """1 − a(wi) at a mirror whose coated face scatters (its finish's albedo: that share is the
        photons', `Tracer.next_event`), else 1."""
        if s.index not in self.mirror_finish:
            return 1.0
        return 1.0 - self.mirror_finish[s.index].albedo(-d, facing(nrm, d))

    def walk(self, b: _Bundle, left: int, step: int, route: tuple[int, ...], turns: int = 0) -> Iterator[Arrival]:
        """Bundle b has just left surface `left`, travelling `step` (+1: in sequence order), after `turns`
        total internal reflections on this branch."""
        if len(b.w) == 0:
            return
        m = left + step
        if m < 0:
            return  # out through the front
        if m == len(self.surfaces):
            if route and len(route) % 2 == 0:
                arrival = self._to_detector(b, route)
                if arrival is not None:
                    yield arrival
            return
        s = self.surfaces[m]
        if self.dummy[m] and self.walls is not None:
            yield from self.walk(b, m, step, route, turns)  # no interface the tracer would see
            return
        p, nrm, w = self._meet(s, b)
        if self.dummy[m]:
            yield from self.walk(_alive(_Bundle(p, b.d, w, b.wl, b.on_glass)), m, step, route, turns)
            return
        glass = np.ones(len(w), bool)
        if s.mirror:
            r = mirror_reflectance(s.coating) * self._specular_share(s, b.d, nrm)
            yield from self.walk(_alive(_Bundle(p, reflect(b.d, nrm), w * r, b.wl, glass)), m, step, route, turns)
            return
        forward = np.einsum("ij,ij->i", b.d, nrm) >= 0.0  # media by the side the ray comes from, as the tracer
        n1 = np.where(forward, s.n_before[b.wl], s.n_after[b.wl])
        n2 = np.where(forward, s.n_after[b.wl], s.n_before[b.wl])
        t_dir, tir, cos_i, _ = refract(b.d, nrm, n1 / n2)
        r = np.where(tir, 0.0, np.clip(reflectance(n1, n2, cos_i, s.coating, self.lam[b.wl]), 0.0, 1.0))
        trans = np.where(tir, 0.0, w * (1.0 - r))
        if self.reflects[m] and len(route) < self.max_reflections:
            bounced = _alive(_Bundle(p, reflect(b.d, nrm), w * r, b.wl, glass))
            yield from self.walk(bounced, m, -step, route + (s.index + 1,), turns)
        if turns < MAX_TIR and np.any(tir & (w > 0)):  # back the way it came, every ray's flux, no Fresnel count
            turned = _alive(_Bundle(p, reflect(b.d, nrm), np.where(tir, w, 0.0), b.wl, glass))
            yield from self.walk(turned, m, -step, route, turns + 1)
        yield from self.walk(_alive(_Bundle(p, t_dir, trans, b.wl, glass)), m, step, route, turns)

    def _meet(self, s, b: _Bundle):
        """Hit points, normals and the flux that gets there within the glass (and past the walls)."""
        shift = np.array([0.0, 0.0, s.z_vertex])
        local = b.o - shift
        t = s.profile.intersect(local, b.d)
        hit = np.isfinite(t) & (t > 1e-9)
        q = local + np.where(hit, t, 0.0)[:, None] * b.d
        if self.walls is None:
            hit &= q[:, 0] ** 2 + q[:, 1] ** 2 <= float(s.clear_semi_diameter) ** 2
        else:
            hit &= self.walls.rims[s.index].holds(q[:, :2])
        p = q + shift
        nrm = s.profile.normal(q)
        w = np.where(hit, b.w, 0.0)
        if self.scene.effects.absorption:  # the glass on the way there absorbs, as in the tracer
            alpha = np.where(np.einsum("ij,ij->i", b.d, nrm) >= 0.0, s.absorption_before[b.wl], s.absorption_after[b.wl])
            w = w * np.exp(-alpha * np.where(hit, t, 0.0))
        if self.walls is not None:
            w = np.where(self.walls.blocked(b.o, p, b.on_glass, w > 0), 0.0, w)
        return p, nrm, w

    def _to_detector(self, b: _Bundle, route) -> Arrival | None:
        det = self.scene.detector
        dz = b.d[:, 2]
        toward = dz > 1e-12  # the detector records light arriving from the lens side only
        t = np.where(toward, (det.z - b.o[:, 2]) / np.where(toward, dz, 1.0), -1.0)
        w = np.where(t > 0, b.w, 0.0)
        p = b.o + np.maximum(t, 0.0)[:, None] * b.d
        if self.walls is not None:
            w = np.where(self.walls.blocked(b.o, p, b.on_glass, w > 0), 0.0, w)
        live = w > 0
        if not live.any():
            return None
        return Arrival(tuple(route), p[live], b.d[live], w[live], b.wl[live])


def _alive(b: _Bundle) -> _Bundle:
    """Only the rays still carrying light: most ghost rays are vignetted early."""
    live = b.w > 0
    if live.all():
        return b
    return _Bundle(b.o[live], b.d[live], b.w[live], b.wl[live], b.on_glass[live])


@dataclass
class GlassRim:
    """Where a surface's faceted face ends, seen along the axis: its outer rim polygon, vertices xy (n, 2)
    in increasing angle `angle` (n,), and the radius of its inner rim (0: a full cap; an annulus's hole
    is taken as the circle through its rim's farthest vertex)."""

    xy: np.ndarray
    angle: np.ndarray
    inner: float

    @classmethod
    def of_triangles(cls, vertices: np.ndarray, triangles: np.ndarray) -> GlassRim:
        edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
        uniq, count = np.unique(edges, axis=0, return_counts=True)
        xy = vertices[np.unique(uniq[count == 1])][:, :2]  # the rim: edges of one triangle only
        r = np.hypot(xy[:, 0], xy[:, 1])
        outer = r >= 0.99 * r.max()
        # A face with a side wall (a cemented interface's ring) has its rim twice, at two z: one vertex an angle.
        angle, first = np.unique(np.round(np.arctan2(xy[outer, 1], xy[outer, 0]), 12), return_index=True)
        return cls(xy[outer][first], angle, float(r[~outer].max()) if (~outer).any() else 0.0)

    @property
    def radius(self) -> float:
        """The farthest reach of the glass from the axis, mm."""
        return float(np.hypot(self.xy[:, 0], self.xy[:, 1]).max())

    def holds(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: points q (N, 2) (xy, mm) lie on the face: inside the rim polygon (on the axis side of
        the rim edge at their angle, the polygon being star-shaped about the axis), outside the hole."""
        k = np.searchsorted(self.angle, np.arctan2(q[:, 1], q[:, 0])) % len(self.angle)
        a, b = self.xy[k - 1], self.xy[k]
        inside = (b[:, 0] - a[:, 0]) * (q[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (q[:, 0] - a[:, 0]) >= 0.0
        return inside & (q[:, 0] ** 2 + q[:, 1] ** 2 >= self.inner ** 2)


def glass_rims(scene) -> dict[int, GlassRim]:
    """Per optical surface (its index) that the scene's mesh has facets for: where that glass ends
    (`GlassRim`). A surface without facets is absent: the tracer meets no interface there."""
    mesh = scene.mesh
    out = {}
    for s in scene.optical:
        tags = [k for k, t in enumerate(mesh.tag_table) if t.role == "optical" and t.surface == s.index]
        tri = mesh.triangles[np.isin(mesh.tags, tags)] if tags else np.zeros((0, 3), np.int64)
        if len(tri):
            out[s.index] = GlassRim.of_triangles(mesh.vertices, tri)
    return out


class Walls:
    """The mount and the glass as ghost light meets them: a segment is blocked where a mechanical face of
    the scene's mesh lies on it, decided by the tracer's own exact query (glass never blocks: routes
    say where the light meets glass); `rims`: where each surface's faceted glass ends (`glass_rims`)."""

    def __init__(self, tracer):
        self.faces = tracer.mechanical
        self.rims = glass_rims(tracer.scene)

    def reach(self, surface) -> float:
        """How far from the axis `surface`'s glass reaches (its clear semi-diameter without facets)."""
        rim = self.rims.get(surface.index)
        return float(surface.clear_semi_diameter) if rim is None else rim.radius

    def blocked(self, start: np.ndarray, end: np.ndarray, on_glass: np.ndarray, live: np.ndarray) -> np.ndarray:
        """(N,) bool: a mechanical face lies on the segment start → end of a live ray (a face at the
        segment's very end too: there the tracer's nearest hit is the metal, not the glass)."""
        out = np.zeros(len(start), bool)
        seg = end - start
        length = np.linalg.norm(seg, axis=1)
        idx = np.flatnonzero(live & (length > 0))
        if idx.size == 0:
            return out
        d = seg[idx] / length[idx, None]
        maybe = self.faces.occluded(start[idx], d, length[idx], on_glass[idx])
        idx, d = idx[maybe], d[maybe]
        if idx.size:
            t, _, lost = self.faces.nearest(start[idx], d, on_glass[idx], np.zeros((len(idx), 3)))
            out[idx] = lost | (t <= length[idx])
        return out


__all__ = ["Arrival", "GlassRim", "Launch", "Walls", "glass_rims", "launch", "reflecting", "reflections_of_order",
           "route_count", "trace_routes", "CENTRED", "MAX_TIR"]
