"""A planar test world for the integrator: flat one-sided faces, a detector, a collimated source.

No optics and no Embree: every face is a rectangle (or disc) with a tag, intersected
in numpy, so the integrator's bookkeeping (weights, π, cos, radii, faces) is checked
against analytic radiometry independently of the tracer engineer's code. Only the
face's front (its normal side) scatters; a ray arriving from behind is absorbed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.scene.scene import Effects
from lensmount.physics.detector import Detector  # noqa: F401  (re-exported for the tests)
from lensmount.physics.rays import RayBatch
from lensmount.trace.tracer import DETECTOR, FACE, GONE, Events, Hits


@dataclass
class Face:
    centre: tuple
    normal: tuple
    u_axis: tuple          # in-plane axis of the first half size
    half: tuple            # (hu, hv) half sizes, or (radius, 0) for a disc
    part: str
    disc: bool = False


@dataclass
class Collimated:
    """Collimated beam travelling along `direction`, filling a disc of radius R around `centre`."""

    direction: tuple
    centre: tuple
    radius: float

    def emit(self, n, rng):
        d = np.asarray(self.direction, float)
        d = d / np.linalg.norm(d)
        a = np.cross(d, [1.0, 0, 0] if abs(d[0]) < 0.9 else [0, 1.0, 0])
        a /= np.linalg.norm(a)
        b = np.cross(d, a)
        r = self.radius * np.sqrt(rng.random(n))
        phi = 2 * math.pi * rng.random(n)
        o = np.asarray(self.centre, float) + (r * np.cos(phi))[:, None] * a + (r * np.sin(phi))[:, None] * b
        flux = math.pi * self.radius**2 / n
        return RayBatch.make(o, np.tile(d, (n, 1)), weight=np.full(n, flux)), flux


@dataclass
class PlanarScene:
    faces: list
    bsdfs: list             # one per face (index = tag)
    detector: Detector
    source: Collimated
    wavelengths_um: tuple = (0.5876,)
    effects: Effects = field(default_factory=Effects)
    optical: list = field(default_factory=list)

    def __post_init__(self):
        verts, tris, tags, table = [], [], [], []
        for t, f in enumerate(self.faces):
            c, n, u = (np.asarray(x, float) for x in (f.centre, f.normal, f.u_axis))
            v = np.cross(n, u)
            hu, hv = f.half if not f.disc else (f.half[0], f.half[0])
            corners = [c - hu * u - hv * v, c + hu * u - hv * v, c + hu * u + hv * v, c - hu * u + hv * v]
            base = len(verts)
            verts += corners
            tris += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
            tags += [t, t]
            table.append(FaceTag(f.part, "barrel", "mount", "x", face=t))
        self.mesh = TaggedMesh(np.array(verts), np.array(tris), np.array(tags), table)
        self.bsdf_of_tag = self.bsdfs
        self.finish_of_tag = ["x"] * len(table)  # Scene's contract: the finish each face has
        self.solid_index_of_tag = np.ones((len(table), len(self.wavelengths_um)))  # no glass: Scene's contract
        self.solid_absorption_of_tag = np.zeros((len(table), len(self.wavelengths_um)))


class PlanarTracer:
    """The real tracer's contract, `next_event(rays, rng, origin_normal) -> Events` and `intersect(rays,
    origin_normal) -> Hits`, on planar faces: vectorised over rays, looping over the few faces. No
    glass, so `rng` is unused."""

    def __init__(self, scene: PlanarScene):
        self.scene = scene

    def next_event(self, rays: RayBatch, rng=None, origin_normal=None) -> Events:
        o, d = rays.origin, rays.direction
        n = len(rays)
        best = np.full(n, np.inf)
        which = np.full(n, -1)
        for t, f in enumerate(self.scene.faces):
            c, nrm, u = (np.asarray(x, float) for x in (f.centre, f.normal, f.u_axis))
            v = np.cross(nrm, u)
            den = d @ nrm
            with np.errstate(divide="ignore", invalid="ignore"):
                tt = ((c - o) @ nrm) / den
            tt = np.where(np.abs(den) > 1e-15, tt, np.inf)
            p = o + np.where(np.isfinite(tt), tt, 0)[:, None] * d
            q = p - c
            if f.disc:
                inside = np.einsum("ij,ij->i", q, q) <= f.half[0] ** 2
            else:
                inside = (np.abs(q @ u) <= f.half[0]) & (np.abs(q @ v) <= f.half[1])
            hit = inside & (tt > 1e-9) & (tt < best)
            best = np.where(hit, tt, best)
            which = np.where(hit, t, which)
        det = self.scene.detector
        with np.errstate(divide="ignore", invalid="ignore"):
            td = (det.z - o[:, 2]) / d[:, 2]
        to_det = (d[:, 2] > 0) & (td > 1e-9) & (td < best)
        kind = np.where(to_det, DETECTOR, np.where(which >= 0, FACE, GONE)).astype(np.int8)
        tt = np.where(to_det, td, best)
        pos = o + np.where(np.isfinite(tt), tt, 0)[:, None] * d
        normals = np.array([f.normal for f in self.scene.faces], float).reshape(-1, 3)
        nrm = normals[np.maximum(which, 0)] if len(normals) else np.zeros((n, 3))
        front = np.einsum("ij,ij->i", nrm, d) < 0
        kind = np.where((kind == FACE) & ~front, GONE, kind).astype(np.int8)  # one-sided faces
        kind = np.where(rays.alive, kind, GONE).astype(np.int8)
        tag = np.where(kind == FACE, which, -1).astype(np.int32)
        prim = np.where(kind == FACE, 2 * which, -1).astype(np.int64)  # each face is two triangles
        pixel = np.where(kind == DETECTOR, det.pixel_of(pos), -1)
        return Events(kind, pos, d.copy(), nrm, tag, prim, pixel, np.where(rays.alive, rays.weight, 0.0),
                      rays.wavelength.copy(), rays.id.copy(), np.zeros(n, bool), np.zeros(n, np.int32),
                      np.full((n, 2), -1, np.int32))


    def intersect(self, rays: RayBatch, origin_normal=None) -> Hits:
        """Nearest hit: the detector when it is nearer than every face (either side of it)."""
        ev = self.next_event(rays)
        det = ev.kind == DETECTOR
        n = len(rays)
        t = np.linalg.norm(ev.position - rays.origin, axis=1)
        return Hits(np.where(ev.kind == GONE, np.inf, t), ev.position, ev.normal, ev.prim, ev.tag,
                    np.full(n, -1, np.int32), det, det, np.zeros(n, bool))


class Lambert:
    """Minimal Lambertian BSDF for the planar world (independent of physics/bsdf)."""

    is_black = False
    is_delta = False
    lobe_half_width_deg = math.inf

    def __init__(self, rho):
        self.rho = rho

    def eval(self, wi, wo, n):
        ok = (np.einsum("ij,ij->i", wi, n) > 0) & (np.einsum("ij,ij->i", wo, n) > 0)
        return np.where(ok, self.rho / math.pi, 0.0)

    def sample(self, wi, n, u):
        r, phi = np.sqrt(u[:, 0]), 2 * math.pi * u[:, 1]
        a = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        t1 = np.cross(n, a)
        t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
        t2 = np.cross(n, t1)
        cos = np.sqrt(np.maximum(1 - u[:, 0], 0))
        wo = (r * np.cos(phi))[:, None] * t1 + (r * np.sin(phi))[:, None] * t2 + cos[:, None] * n
        return wo, np.full(len(u), self.rho), cos / math.pi
