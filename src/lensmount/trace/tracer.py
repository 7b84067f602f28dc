"""The non-sequential tracer: one Embree scene, batched queries, float64 refinement.

    tracer = Tracer(scene)
    hits = tracer.intersect(rays)            # nearest surface (mesh or detector), refined
    events = tracer.next_event(rays, rng)    # through the glass to a mechanical face, the detector, or out

How a query stays exact although Embree is float32 (docs/tracer.md):

1. *Centred float32, two scenes.* Embree gets vertices minus the assembly's bounding-box
   centre, glass facets and mechanical faces in separate scenes. Embree only answers "which
   triangle, roughly where".
2. *Float64 truth on the ray's own line.* Glass: every facet hit is re-intersected with the
   analytic `Profile` of its surface (point and normal are the analytic ones: as exact as a
   sequential trace); a facet with no crossing near it (the chord of the surface just left)
   is skipped by relaunching just beyond it on the same line. Metal: float64 Möller–Trumbore
   against the candidate and, near its edges, every triangle sharing a vertex with it
   (`lensmount.trace.mechanical`). The line is never moved sideways; every event point lies
   on it, inside its triangle.
3. *Leaving a face.* No global offset: a ray leaving glass or a mechanical face meets every
   mechanical face beyond it, however close (metal touching glass at gap 0 included); only the
   face it leaves (coplanar, at t ≈ 0) and faces it does not enter are not hits.

Media come from the prescription (n_before / n_after of surface i by the sign of d·n), never
from which solid was hit, so cemented interfaces (two coincident facet sets, one surface index)
need no per-ray medium state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.trace import kernels, lens_kernel
from lensmount.trace.ghosts import reflecting
from lensmount.optics.snell import reflect, refract
from lensmount.physics.interfaces import facing, mirror_reflectance, reflectance
from lensmount.trace.mechanical import MechanicalFaces
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import ray_streams
from lensmount.scene.scene import scattering_mirror_tags

GONE, FACE, DETECTOR = 0, 1, 2  # Events.kind: the one set of event codes (the integrators use these)
FRESNEL_DIM = 1 << 20  # Streams dimensions of the Fresnel branch: FRESNEL_DIM + interface count in the call
MIRROR_SCATTER_DIM = 1 << 21  # ... and of a scattering mirror's branch: MIRROR_SCATTER_DIM + interface count
MIRROR_SCATTER_MIN_SHARE = 0.1  # a scattering mirror's branch takes its finish at least this often (`_scatters`)

_MAX_SKIPS = 32          # relaunches per query before a ray is declared lost
_MAX_OPTICAL = 256       # refractions/reflections per next_event call: beyond, a ray is trapped in the glass
_EPS_REL = 2e-6          # relaunch step past a fake glass facet, relative to the assembly size
_TMIN_REL = 1e-10        # float64 self-hit threshold, relative to the assembly size
_EMBREE_MISS = 1e30
_REACH_BANDS = 64        # radial bands of each glass surface's facet z range (Tracer._optical_faces)


@dataclass
class Hits:
    """Nearest hit of N rays.

    t : (N,) float64 distance along the ray (inf = nothing)
    point : (N, 3) float64 hit points (the origin where nothing was hit)
    normal : (N, 3) unit normal: analytic and oriented +z for optical faces, the triangle's
        outward normal for mechanical faces, (0, 0, -1) on the detector
    prim : (N,) int64 triangle index, -1 for detector or miss (and for glass hits found by the
        sequential step inside `next_event`, which needs no facet)
    tag : (N,) int32 mesh tag, -1 for detector or miss
    surface : (N,) int32 index into `scene.optical` for optical faces, else -1
    detector : (N,) bool, the detector rectangle is the nearest
    detector_front : (N,) bool, it was hit from the lens side (direction z > 0)
    lost : (N,) bool, the query could not be resolved (numerical guard; treat as absorbed)
    """

    t: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    prim: np.ndarray
    tag: np.ndarray
    surface: np.ndarray
    detector: np.ndarray
    detector_front: np.ndarray
    lost: np.ndarray


@dataclass
class Events:
    """Where each of N rays ended one `next_event` call.

    kind : (N,) int8: GONE (escaped, absorbed by the detector's back, lost or dead on input),
        FACE (a mechanical face: scatter or absorb there; or a mirror's coated face the ray scatters
        at, `next_event`), DETECTOR (front of the detector)
    position : (N, 3) event point (the last point on the ray for GONE)
    direction : (N, 3) unit travel direction arriving at the event (wi = -direction)
    normal : (N, 3) unit face normal on the side the ray came from (FACE; (0,0,-1) on DETECTOR)
    tag : (N,) int32 mesh tag for FACE, else -1
    prim : (N,) int64 triangle for FACE, else -1
    pixel : (N,) int64 flat detector pixel for DETECTOR, else -1
    weight : (N,) throughput after the optics (Fresnel transmittance when ghosts are off, bulk
        absorption in the glass when `effects.absorption` is on); 0 for a ray trapped in the glass
        by total internal reflection (GONE after _MAX_OPTICAL interfaces: absorbed there)
    wavelength, id : (N,) carried through
    lost : (N,) bool, ended by a numerical guard (its weight is the lost flux)
    reflections : (N,) int32 Fresnel (ghost) reflections during this call (TIR not counted)
    ghost_pair : (N, 2) int32 the optical surfaces (positions in `scene.optical`) of the first two of
        them, in order; -1 where fewer happened (the path signature's ghost pair)
    """

    kind: np.ndarray
    position: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    tag: np.ndarray
    prim: np.ndarray
    pixel: np.ndarray
    weight: np.ndarray
    wavelength: np.ndarray
    id: np.ndarray
    lost: np.ndarray
    reflections: np.ndarray
    ghost_pair: np.ndarray

    def __len__(self) -> int:
        return len(self.kind)


class Tracer:
    """Intersection and optical interfaces for one Scene (see the module docstring).

    Attributes: centre (3,) Embree frame origin; extent (mm, largest bounding-box side);
    eps (relaunch step past a fake glass facet, mm); t_min (float64 |t| below which a hit
    is at the ray's origin, mm); mechanical (`MechanicalFaces`).
    """

    def __init__(self, scene):
        from embreex import rtcore_scene as rtcs  # lazy: keeps lensmount --help from loading embreex
        from embreex.mesh_construction import TriangleMesh

        self.scene = scene
        self._optical_queries = 0
        self.segments = 0  # straight pieces of traced paths (one per interface, plus the last), for benchmarks
        mesh = scene.mesh
        if not np.all(np.isfinite(mesh.vertices)):
            raise ValueError("the scene's mesh has non-finite vertices (a tessellation bug upstream)")
        # The frame and the offsets follow the mesh alone (the detector is analytic): float32
        # keeps ~7 digits of the largest centred coordinate.
        pts = mesh.vertices if len(mesh.vertices) else np.zeros((1, 3))
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self.centre = 0.5 * (lo + hi)
        self.extent = float(max(np.max(hi - lo), 1e-6))
        self.eps = _EPS_REL * self.extent
        self.t_min = _TMIN_REL * self.extent

        tri = mesh.triangles
        self._has_mesh = len(tri) > 0
        # Float64 triangle planes (outward normals for CAD solids).
        v0 = mesh.vertices[tri[:, 0]] if self._has_mesh else np.zeros((0, 3))
        nrm = (np.cross(mesh.vertices[tri[:, 1]] - v0, mesh.vertices[tri[:, 2]] - v0)
               if self._has_mesh else np.zeros((0, 3)))
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        self._tri_v0 = v0
        self._tri_n = np.where(length > 0, nrm / np.where(length > 0, length, 1.0), 0.0)
        self._tri_tag = mesh.tags.astype(np.int32)

        # Optical surfaces: tag -> position in scene.optical.
        pos_of_surface = {s.index: k for k, s in enumerate(scene.optical)}
        tag_surface = np.array([pos_of_surface.get(t.surface, -1) if t.role == "optical" else -1
                                for t in mesh.tag_table] or [-1], np.int32)
        self._tri_surface = tag_surface[self._tri_tag] if self._has_mesh else np.zeros(0, np.int32)
        self._profiles = [s.profile for s in scene.optical]
        self._z_vertex = np.array([s.z_vertex for s in scene.optical] or [0.0])
        self._curvature = np.array([s.profile.curvature for s in scene.optical] or [0.0])
        self._conic = np.array([s.profile.conic for s in scene.optical] or [0.0])
        w = len(scene.wavelengths_um)
        self._n_before = np.array([np.broadcast_to(s.n_before, (w,)) for s in scene.optical] or [np.ones(w)])
        self._n_after = np.array([np.broadcast_to(s.n_after, (w,)) for s in scene.optical] or [np.ones(w)])
        self._wavelengths = np.asarray(scene.wavelengths_um, np.float64)
        self._alpha_before = np.array([np.broadcast_to(s.absorption_before, (w,)) for s in scene.optical]
                                      or [np.zeros(w)])
        self._alpha_after = np.array([np.broadcast_to(s.absorption_after, (w,)) for s in scene.optical]
                                     or [np.zeros(w)])
        self._alpha_solid = np.asarray(scene.solid_absorption_of_tag, np.float64)
        self._absorbs = bool(scene.effects.absorption) and bool(
            self._alpha_before.any() or self._alpha_after.any() or self._alpha_solid.any())
        self._mirror = np.array([s.mirror for s in scene.optical] or [False])
        self._mirror_r = np.array([mirror_reflectance(s.coating) for s in scene.optical] or [1.0])
        self._mirror_face = self._scattering_mirror_faces()
        # The reflection branch only where a ghost can exist (the planner's "ghosts" line): with every
        # surface perfect AR it would draw a number per crossing and never reflect.
        self.fresnel_branch = bool(scene.effects.ghosts) and bool(reflecting(scene).any())
        self._tolerance = self._facet_tolerance()
        # Two Embree scenes: glass facets (refined against the analytic surfaces) and the
        # mechanical faces (decided exactly in float64, lensmount.trace.mechanical). Apart,
        # skipping a facet of the surface a ray leaves can never skip metal touching the glass.
        optical = np.flatnonzero(self._tri_surface >= 0)
        self._optical_prims = optical
        self._has_optical = optical.size > 0
        if self._has_optical:
            self._embree = rtcs.EmbreeScene()
            TriangleMesh(self._embree, (mesh.vertices - self.centre).astype(np.float32),
                         tri[optical].astype(np.int32))
        self._faces = self._optical_faces()
        mech = tri[self._tri_surface < 0] if self._has_mesh else np.zeros((0, 3), np.int64)
        lens = lens_kernel.LensTables(
            self._faces, self._curvature, self._conic, self.t_min, self._n_before, self._n_after,
            self._alpha_before, self._alpha_after, self._absorbs,
            np.array([lens_kernel.COATING_CODES[s.coating.kind] for s in scene.optical] or [0]),
            np.array([s.coating.reflectance for s in scene.optical] or [0.0]), self._wavelengths, self._mirror)
        detector = lens_kernel.DetectorPlane(float(scene.detector.z), 0.5 * scene.detector.width,
                                             0.5 * scene.detector.height)
        self._walk = (lens, lens_kernel.clear_bore(*(mesh.vertices[mech[:, k]] for k in range(3))), detector)
        self.mechanical = MechanicalFaces(mesh.vertices, tri, self._tri_n, np.flatnonzero(self._tri_surface < 0),
                                          self.centre, self.extent, self.t_min)

    @property
    def embree_rays(self) -> int:
        """Rays sent to Embree so far (both scenes, relaunches included), for benchmarks."""
        return self._optical_queries + self.mechanical.queries

    @embree_rays.setter
    def embree_rays(self, value: int) -> None:
        self._optical_queries = value
        self.mechanical.queries = 0

    # ------------------------------------------------------------------ intersection

    def _facet_tolerance(self) -> np.ndarray:
        """Per optical surface: how far its facets may lie from the analytic surface (mm), padded."""
        tol = np.full(max(len(self._profiles), 1), 0.0)
        if self._has_mesh:
            mesh = self.scene.mesh
            c = mesh.vertices[mesh.triangles].mean(axis=1)
            for k, prof in enumerate(self._profiles):
                sel = self._tri_surface == k
                if sel.any():
                    r2 = c[sel, 0] ** 2 + c[sel, 1] ** 2
                    dev = np.abs(c[sel, 2] - self._z_vertex[k] - prof.sag(r2))
                    dev = dev[np.isfinite(dev)]
                    tol[k] = float(dev.max()) if dev.size else 0.0
        return 4.0 * tol + 100.0 * self.eps

    def _optical_faces(self):
        """Per optical surface: (safe radius, z slab (2,)) of its facets, for the sequential step, with
        the next faceted surface up and down and the conic, as one `kernels.face_table`.

        safe radius: inside it the facets certainly cover the analytic surface (the outer
        boundary polygon's inscribed radius; 0 for a surface without facets, an annulus or an
        asphere, which the step leaves to Embree); slab: z range of the facets padded by the
        facet tolerance, inf-wide where unknown; reach (k_n, _REACH_BANDS, 2), reach_inv (k_n,): the
        padded z range of the facets that come within radius (b + 1) / reach_inv of the axis (a path
        that stays nearer the axis meets no other facet outside it: the rim of a concave face
        reaches far in z, its centre does not).
        """
        k_n = len(self._profiles)
        safe = np.zeros(max(k_n, 1))
        slab = np.tile([np.inf, -np.inf], (max(k_n, 1), 1))
        reach = np.tile([np.inf, -np.inf], (max(k_n, 1), _REACH_BANDS, 1))
        reach_inv = np.zeros(max(k_n, 1))
        if not self._has_mesh:
            none = np.full(max(k_n, 1), -1)
            return kernels.face_table(none, none, safe, slab, reach, reach_inv, self._z_vertex, self._curvature,
                                      self._conic)
        mesh = self.scene.mesh
        for k in range(k_n):
            tri = mesh.triangles[self._tri_surface == k]
            if not len(tri):
                continue
            v = mesh.vertices[np.unique(tri)]
            slab[k] = v[:, 2].min() - self._tolerance[k], v[:, 2].max() + self._tolerance[k]
            corners = [mesh.vertices[tri[:, j]] for j in range(3)]
            r_near = lens_kernel.axis_distance(*corners)
            z = np.column_stack([c[:, 2] for c in corners])
            reach_inv[k] = (_REACH_BANDS - 1) / max(float(r_near.max()), 1e-300)
            band = np.minimum(np.floor(r_near * reach_inv[k]).astype(np.int64), _REACH_BANDS - 1)
            lo, hi = np.full(_REACH_BANDS, np.inf), np.full(_REACH_BANDS, -np.inf)
            np.minimum.at(lo, band, z.min(axis=1) - self._tolerance[k])
            np.maximum.at(hi, band, z.max(axis=1) + self._tolerance[k])
            reach[k, :, 0], reach[k, :, 1] = np.minimum.accumulate(lo), np.maximum.accumulate(hi)
            edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
            uniq, count = np.unique(edges, axis=0, return_counts=True)
            rim = uniq[count == 1]
            a, b = mesh.vertices[rim[:, 0], :2], mesh.vertices[rim[:, 1], :2]
            r = np.hypot(v[:, 0], v[:, 1])
            r_rim = np.hypot(*mesh.vertices[np.unique(rim)][:, :2].T) if len(rim) else r
            if not self._profiles[k].is_conic or not len(rim) or r_rim.min() < 0.99 * r_rim.max():
                continue  # an asphere, or an annulus (a second, inner rim): Embree decides
            # Distance from the axis to each rim edge (as a segment in xy).
            ab = b - a
            u = np.clip(-np.einsum("ij,ij->i", a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0, 1)
            safe[k] = max(float(np.hypot(*(a + u[:, None] * ab).T).min()) - self._tolerance[k], 0.0)
        # The next surface with facets in each direction (a stop in air has none).
        faceted = np.isfinite(slab[:k_n, 0])
        up, down = np.full(max(k_n, 1), -1), np.full(max(k_n, 1), -1)
        for k in range(k_n):
            above = np.flatnonzero(faceted[k + 1:])
            below = np.flatnonzero(faceted[:k])
            up[k] = k + 1 + above[0] if above.size else -1
            down[k] = below[-1] if below.size else -1
        return kernels.face_table(up, down, safe, slab, reach, reach_inv, self._z_vertex, self._curvature, self._conic)

    def _scattering_mirror_faces(self) -> np.ndarray:
        """(K, 2) per optical surface: (tag, triangle) of its coated face where the scene lets it
        scatter (a mirror with a finish, `scene.scattering_mirror_tags`), else (-1, -1). The triangle is the
        face's one nearest the axis: an event found by the sequential step has none of its own."""
        out = np.full((max(len(self._profiles), 1), 2), -1, np.int64)
        tag_of = scattering_mirror_tags(self.scene)
        for k, s in enumerate(self.scene.optical):
            prims = np.flatnonzero(self._tri_tag == tag_of[s.index]) if s.index in tag_of else np.zeros(0, np.int64)
            if prims.size:
                c = self.scene.mesh.vertices[self.scene.mesh.triangles[prims]].mean(axis=1)
                out[k] = tag_of[s.index], prims[np.argmin(np.hypot(c[:, 0], c[:, 1]))]
        return out

    def _embree_query(self, start: np.ndarray, d: np.ndarray):
        """Optical-facet candidates: (local facet index (m,) or -1, float32 distance from start)."""
        self._optical_queries += len(start)
        res = self._embree.run((start - self.centre).astype(np.float32), d.astype(np.float32),
                               query="INTERSECT", output=1)
        prim = res["primID"].astype(np.int64)
        t = res["tfar"].astype(np.float64)
        return np.where((prim >= 0) & (t < _EMBREE_MISS), prim, -1), t

    def _conic_roots(self, k, o: np.ndarray, d: np.ndarray) -> list[np.ndarray]:
        """Both float64 crossings (n,) of rays with conic surface k (an int, or (n,) per ray);
        inf where none, behind t_min or off the vertex sheet."""
        n = len(o)
        per_ray = [np.broadcast_to(v[k], (n,)) for v in (self._curvature, 1.0 + self._conic, self._z_vertex)]
        return list(kernels.conic_roots(*per_ray, self.t_min, o, d))

    def _optical_root(self, k: int, o: np.ndarray, d: np.ndarray, t_guess: np.ndarray) -> np.ndarray:
        """Float64 crossing of rays (n,) with optical surface k nearest to the facet hit t_guess.

        Both roots of the conic are candidates (a ray can cross a strongly curved surface twice,
        e.g. after a reflection); only those on the vertex sheet, beyond t_min and consistent
        with the facet hit are kept. Aspheres: Newton from the facet hit. inf = not a real hit.
        """
        prof = self._profiles[k]
        if not prof.is_conic:
            ol = o - np.array([0.0, 0.0, self._z_vertex[k]])
            t = _newton_asphere(prof, ol, d, t_guess)
            z = ol[:, 2] + np.where(np.isfinite(t), t, 0.0) * d[:, 2]
            sheet = (1.0 + prof.conic) * prof.curvature * z <= 1.0 + 1e-12
            return np.where(np.isfinite(t) & (t > self.t_min) & sheet, t, np.inf)
        best = np.full(len(o), np.inf)
        for t in self._conic_roots(k, o, d):
            closer = np.isfinite(t) & (np.abs(t - t_guess) < np.abs(best - t_guess))
            best = np.where(closer, t, best)
        return best

    def _sequential_step(self, left: np.ndarray, o: np.ndarray, d: np.ndarray, t_stop: np.ndarray):
        """The next optical hit of rays (n,) that just left optical surface `left`, without Embree.

        A ray leaving surface k meets, before t_stop (the nearest metal), either surface k ± 1
        (the next one in its direction of travel) or k again, unless its path enters the slab of
        any other surface. The analytic crossing is exact where it lies inside the facets'
        safe radius; elsewhere (near a rim, other slabs in the way, aspheres) the step declines.
        Returns (sure (n,) bool, t (n,) inf = no optical hit before t_stop, surface (n,)).
        """
        return kernels.sequential_step(np.asarray(left, np.int64), o, d, np.asarray(t_stop, np.float64), self._faces,
                                       self.t_min)

    def _optical_nearest(self, o: np.ndarray, d: np.ndarray, t_stop: np.ndarray):
        """Nearest analytic optical hit of rays (n,) before t_stop: (t, prim, normal, lost).

        A facet hit is refined on the ray's own line against its surface's `Profile`; a facet
        with no crossing of its surface near it (the chord of the surface just left) is skipped
        by relaunching just beyond it on the same line.
        """
        n = len(o)
        t_hit = np.full(n, np.inf)
        prim = np.full(n, -1, np.int64)
        normal = np.zeros((n, 3))
        lost = np.zeros(n, bool)
        if not self._has_optical or n == 0:
            return t_hit, prim, normal, lost
        base = np.zeros(n)
        todo = np.arange(n)
        for round_ in range(_MAX_SKIPS):
            if todo.size == 0:
                break
            oo, dd = o[todo], d[todo]
            p, te = self._embree_query(oo + base[todo, None] * dd, dd)
            te = te + base[todo]
            hit = (p >= 0) & (te <= t_stop[todo] + self.eps)
            p = np.where(hit, self._optical_prims[np.where(hit, p, 0)], -1)
            t64 = np.full(len(todo), np.inf)
            nn = np.zeros((len(todo), 3))
            surf = np.where(hit, self._tri_surface[np.maximum(p, 0)], -1)
            for k in np.unique(surf[hit]):
                sel = hit & (surf == k)
                ta = self._optical_root(int(k), oo[sel], dd[sel], te[sel])
                pl = oo[sel] + np.where(np.isfinite(ta), ta, 0.0)[:, None] * dd[sel]
                pl[:, 2] -= self._z_vertex[k]
                nk = self._profiles[k].normal(pl)
                cos = np.abs(np.einsum("ij,ij->i", nk, dd[sel]))
                near = np.abs(ta - te[sel]) * np.maximum(cos, 1e-3) <= self._tolerance[k]
                t64[sel] = np.where(np.isfinite(ta) & near, ta, np.inf)
                nn[sel] = nk
            done = ~hit | np.isfinite(t64)
            idx = todo[done & hit]
            t_hit[idx] = t64[done & hit]
            prim[idx] = p[done & hit]
            normal[idx] = nn[done & hit]
            again = ~done
            base[todo[again]] = te[again] + self.eps * 2.0 ** max(0, round_ - 8)
            todo = todo[again]
        lost[todo] = True
        return t_hit, prim, normal, lost

    def _nearest(self, o: np.ndarray, d: np.ndarray, leaving: np.ndarray | None = None,
                 left_normal: np.ndarray | None = None, left_surface: np.ndarray | None = None) -> Hits:
        """Nearest refined hit for rays (n, 3) in float64 (see the module docstring).

        leaving (n,) bool: the ray starts on a face it is leaving (then a mechanical face that
        touches the origin and that the ray enters is a hit at t = 0); left_normal (n, 3): the
        normal of that face when it is mechanical (faces coplanar with it are not hits at t = 0);
        left_surface (n,): the optical surface (position in scene.optical) a ray just left, -1
        for none (then the next glass surface may come from the sequential step, without Embree).
        """
        n = len(o)
        if leaving is None:
            leaving = np.zeros(n, bool)
        if left_normal is None:
            left_normal = np.zeros((n, 3))
        t_mech = np.full(n, np.inf)
        prim_mech = np.full(n, -1, np.int64)
        lost = np.zeros(n, bool)
        t_opt = np.full(n, np.inf)
        s_opt = np.full(n, -1, np.int64)
        prim_opt = np.full(n, -1, np.int64)
        n_opt = np.zeros((n, 3))
        lost_opt = np.zeros(n, bool)
        rest = np.ones(n, bool)
        if left_surface is not None and self._has_optical:
            # Inside the lens: the analytic step to the next glass surface, then one occlusion
            # query against the metal on that segment (a nearest-hit query only if it is blocked).
            sure, t_seq, s_seq = self._sequential_step(left_surface, o, d, np.full(n, np.inf))
            sure &= np.isfinite(t_seq)
            si = np.flatnonzero(sure)
            clear = ~self.mechanical.occluded(o[si], d[si], t_seq[si], leaving[si])
            done = si[clear]
            t_opt[done], s_opt[done] = t_seq[done], s_seq[done]
            rest[done] = False
        ri = np.flatnonzero(rest)
        t_mech[ri], prim_mech[ri], lost[ri] = self.mechanical.nearest(o[ri], d[ri], leaving[ri], left_normal[ri])
        if left_surface is not None and self._has_optical and ri.size:
            sure, t_seq, s_seq = self._sequential_step(left_surface[ri], o[ri], d[ri], t_mech[ri])
            t_opt[ri[sure]], s_opt[ri[sure]] = t_seq[sure], s_seq[sure]
            rest[ri[sure]] = False
        if rest.any():
            t_r, p_r, n_opt[rest], lost_opt[rest] = self._optical_nearest(o[rest], d[rest], t_mech[rest])
            t_opt[rest], prim_opt[rest] = t_r, p_r
            s_opt[rest] = np.where(p_r >= 0, self._tri_surface[np.maximum(p_r, 0)] if self._has_mesh else -1, -1)
        seq = ~rest & np.isfinite(t_opt)
        for k in np.unique(s_opt[seq]):
            sel = seq & (s_opt == k)
            pl = o[sel] + t_opt[sel, None] * d[sel]
            pl[:, 2] -= self._z_vertex[k]
            n_opt[sel] = self._profiles[k].normal(pl)
        glass = t_opt < t_mech
        t_hit = np.where(glass, t_opt, t_mech)
        prim = np.where(glass, prim_opt, prim_mech)  # -1 for a glass hit from the sequential step
        surface = np.where(glass, s_opt, -1)
        lost = np.where(glass, lost_opt, lost | (lost_opt & ~np.isfinite(t_hit)))
        mech = ~glass & (prim_mech >= 0)
        normal = np.where(glass[:, None], n_opt, 0.0)
        normal[mech] = self._tri_n[prim[mech]]
        # The detector rectangle, analytic, merged with the mesh hit: nearest wins.
        t_det, front = self.scene.detector.intersect(o, d, self.t_min)
        on_det = t_det < t_hit
        t = np.where(on_det, t_det, t_hit)
        lost &= ~on_det
        prim = np.where(on_det, -1, prim)
        surface = np.where(on_det, -1, surface)
        tag = np.where(prim >= 0, self._tri_tag[np.maximum(prim, 0)] if self._has_mesh else -1, -1).astype(np.int32)
        normal = np.where(on_det[:, None], np.array([0.0, 0.0, -1.0]), normal)
        point = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d
        return Hits(t, point, normal, prim, tag, surface.astype(np.int32), on_det, on_det & front, lost)

    def intersect(self, rays: RayBatch, origin_normal: np.ndarray | None = None) -> Hits:
        """Nearest hit of every ray (dead rays included; callers mask with `rays.alive`).

        origin_normal (N, 3), optional: normal of the surface each ray starts on (e.g. the
        `Events.normal` of the event it was scattered at; zeros for rays in free space).
        """
        left = _left_normal(origin_normal, len(rays))
        return self._nearest(rays.origin, rays.direction, np.any(left != 0.0, axis=1), left)

    # ------------------------------------------------------------------ events

    def next_event(self, rays: RayBatch, rng: np.random.Generator | None = None,
                   origin_normal: np.ndarray | None = None) -> Events:
        """Carry live rays through the optics until a mechanical face (or a scattering mirror's
        face), the detector, or out.

        Along every segment inside glass the weight is multiplied by exp(-a(λ) L) (bulk
        absorption, `effects.absorption`). At every optical hit: media from the prescription, Snell refraction with the
        wavelength's index, total internal reflection, and the coating's reflectance R. With
        `effects.ghosts` off (or no surface that can reflect, `fresnel_branch`) the ray transmits and its
        weight is multiplied by T = 1 − R; with ghosts on it reflects with probability R (weight unchanged) using `rng`: a
        `sampler.Streams` aligned with `rays` (ray i's k-th interface in this call draws dimension
        FRESNEL_DIM + k of its own stream, so the branch does not depend on the batch), or a
        Generator. A mirror reflects every ray with weight R (its coating); where the scene gives
        its coated face a finish (`[assign] "surface:N"`, and the face scatters by `[effects]`) a
        ray ends there as a FACE event (its tag, the arriving direction, weight R·a/p) with
        probability p = max(a, MIRROR_SCATTER_MIN_SHARE) (a(wi): the finish's albedo at that
        incidence; p = 0 where a = 0; dimension MIRROR_SCATTER_DIM + k), and reflects specularly
        otherwise with R(1 − a)/(1 − p): R(1 − a) specular and R·a scattered on average, the walk
        sampling the scatter (`physics.bsdf.mirror_finish.MirrorFinish`). Without `rng` every ray reflects
        specularly with R. The input batch is not modified.

        origin_normal (N, 3), optional (addition to the architecture's signature): the normal of
        the surface each ray starts on — pass `Events.normal` of the event a ray was scattered at.
        With it, a ray meets every face beyond the one it leaves however close (a neighbour at
        a concave corner at t = 0); without it, no face at t ≈ 0 is a hit (the ray is taken to
        start on it), so a neighbouring face touching the origin is missed.
        """
        n = len(rays)
        o = rays.origin.copy()
        d = rays.direction.copy()
        w = np.where(rays.alive, rays.weight, 0.0)
        wl = rays.wavelength.astype(np.int64)
        kind = np.full(n, GONE, np.int8)
        normal = np.zeros((n, 3))
        tag = np.full(n, -1, np.int32)
        prim = np.full(n, -1, np.int64)
        reflections = np.zeros(n, np.int32)
        ghost_pair = np.full((n, 2), -1, np.int32)
        ghosts = self.fresnel_branch
        scattering_mirror = bool(np.any(self._mirror_face[:, 0] >= 0)) and rng is not None
        streams = ray_streams(rng, n) if (ghosts or scattering_mirror) and rng is not None else None
        left_n = _left_normal(origin_normal, n)  # the mechanical face a ray leaves (zeros: none)
        leaving = np.any(left_n != 0.0, axis=1)
        left_s = np.full(n, -1, np.int64)  # the glass surface a ray just left
        count = np.zeros(n, np.int64)  # optical interfaces so far in this call, per ray
        keys = streams.keys if streams is not None else np.zeros(0, np.uint64)
        valid = np.all(np.isfinite(o), axis=1) & np.all(np.isfinite(d), axis=1) & np.isfinite(w)
        valid &= np.abs(np.linalg.norm(np.where(np.isfinite(d), d, 0.0), axis=1) - 1.0) < 1e-6
        lost = rays.alive & (w > 0) & ~valid  # a malformed ray is a numerical loss, not light
        work = np.flatnonzero(rays.alive & (w > 0) & valid)
        started = work
        while work.size:
            if self._has_optical:
                # Inside the lens: every step that needs no Embree, compiled, in place (lens_kernel).
                over = lens_kernel.walk(work, o, d, w, wl, left_s, leaving, left_n, count, kind, normal,
                                        reflections, ghost_pair, lost, keys, ghosts, *self._walk, FRESNEL_DIM,
                                        _MAX_OPTICAL)
                work = work[~over]
            # Still bouncing inside the glass after _MAX_OPTICAL interfaces: trapped by total internal
            # reflection (a skew ray circling an element's rim between two faces that both reflect it
            # totally keeps its distance from the axis, so it never reaches the edge). A real one is
            # absorbed along its endless path; so is this one (weight 0: the ledger's 'glass'), not lost.
            spent = count[work] >= _MAX_OPTICAL
            w[work[spent]] = 0.0
            work = work[~spent]
            if work.size == 0:
                break
            h = self._nearest(o[work], d[work], leaving[work], left_n[work], left_s[work])
            if self._absorbs:
                w[work] *= self._bulk_transmittance(h, d[work], wl[work])
            o[work] = h.point
            lost[work[h.lost]] = True
            det = h.detector & h.detector_front
            kind[work[det]] = DETECTOR
            normal[work[det]] = (0.0, 0.0, -1.0)
            face = (h.prim >= 0) & (h.surface < 0) & ~h.detector & np.isfinite(h.t)
            fi = work[face]
            kind[fi] = FACE
            tag[fi] = h.tag[face]
            prim[fi] = h.prim[face]
            normal[fi] = facing(h.normal[face], d[fi])
            glass = (h.surface >= 0) & np.isfinite(h.t)
            gi = work[glass]
            if gi.size:
                d_in = d[gi]
                u = streams.at(gi, FRESNEL_DIM + count[gi]) if ghosts and streams is not None else None
                d[gi], w[gi], refl = self._interface(h.surface[glass], h.normal[glass], d[gi], w[gi], wl[gi],
                                                     ghosts, u)
                count[gi] += 1
                reflections[gi] += refl
                r, s = gi[refl > 0], h.surface[glass][refl > 0]
                slot = np.where(ghost_pair[r, 0] < 0, 0, 1)
                free = ghost_pair[r, slot] < 0
                ghost_pair[r[free], slot[free]] = s[free]
                leaving[gi] = True  # it leaves glass: metal touching it is a hit at t = 0
                left_n[gi] = 0.0
                left_s[gi] = h.surface[glass]
                bad = ~(np.all(np.isfinite(d[gi]), axis=1) & np.isfinite(w[gi]))
                lost[gi[bad]] = True
                keep = ~bad
                if scattering_mirror:  # the finish's share ends here, on the mirror's face (the walk scatters it)
                    on, share = self._scatters(h.surface[glass], h.normal[glass], d_in,
                                               streams.at(gi, MIRROR_SCATTER_DIM + count[gi] - 1))
                    on &= keep
                    w[gi] *= share
                    si, k, nk = gi[on], h.surface[glass][on], h.normal[glass][on]
                    kind[si], tag[si], prim[si] = FACE, self._mirror_face[k, 0], self._mirror_face[k, 1]
                    normal[si] = facing(nk, d_in[on])
                    d[si] = d_in[on]
                    keep &= ~on
                gi = gi[keep]
            work = gi
        self.segments += started.size + int(count[started].sum())
        kind[lost] = GONE
        pixel = np.full(n, -1, np.int64)
        on = kind == DETECTOR
        pixel[on] = self.scene.detector.pixel_of(o[on])
        o = np.where(np.isfinite(o), o, 0.0)
        d = np.where(np.all(np.isfinite(d), axis=1, keepdims=True), d, 0.0)
        w = np.where(np.isfinite(w) & rays.alive, w, 0.0)
        return Events(kind, o, d, normal, tag, prim, pixel, w, rays.wavelength.copy(), rays.id.copy(), lost,
                      reflections, ghost_pair)

    def _scatters(self, surf: np.ndarray, nrm: np.ndarray, d_in: np.ndarray, u: np.ndarray):
        """Which rays scatter at the optical surfaces `surf` they met (normals nrm, arriving along
        d_in; u (m,) uniforms), and the factor on their weight: (on (m,) bool, share (m,)).

        At a mirror with a finish of albedo a (at that incidence; its TIS at normal incidence) a ray
        scatters with probability p = max(a, MIRROR_SCATTER_MIN_SHARE) where a > 0, carrying a/p,
        else it reflects with (1 − a)/(1 − p): R·a scattered and R(1 − a) specular on average for any
        p. Why a floor: a polished mirror's TIS is ~1e-3, so p = a would send one photon in a thousand
        down the primary's scatter, the main stray path of a Cassegrain; at p = 0.1 a hundred times
        more, for 10 % fewer specular ones. Elsewhere on = False, share = 1."""
        on, share = np.zeros(len(surf), bool), np.ones(len(surf))
        bsdf_of_tag = self.scene.bsdf_of_tag
        for k in np.unique(surf[self._mirror_face[surf, 0] >= 0]):
            sel = surf == k
            a = bsdf_of_tag[self._mirror_face[k, 0]].finish.albedo(-d_in[sel], facing(nrm[sel], d_in[sel]))
            p = np.where(a > 0.0, np.maximum(a, MIRROR_SCATTER_MIN_SHARE), 0.0)
            on[sel] = u[sel] < p
            share[sel] = np.where(on[sel], a / np.where(p > 0.0, p, 1.0), (1.0 - a) / np.maximum(1.0 - p, 1e-300))
        return on, share

    def _bulk_transmittance(self, h: Hits, d: np.ndarray, wl: np.ndarray) -> np.ndarray:
        """exp(-a(λ) L) over the segment each ray just travelled (its length h.t).

        The medium is read at the segment's end, like n1 in `_interface`: at a glass surface the
        side the ray arrives from (before for d·n >= 0, else after); at a face of a lens part
        reached from inside (d · outward normal > 0) that part's glass; else air (a = 0). So
        photons and backward rays, direct light and stray light, are absorbed alike.
        """
        alpha = np.zeros(len(d))
        found = np.isfinite(h.t)
        glass = (h.surface >= 0) & found
        s, wg = h.surface[glass], wl[glass]
        forward = np.einsum("ij,ij->i", d[glass], h.normal[glass]) >= 0.0
        alpha[glass] = np.where(forward, self._alpha_before[s, wg], self._alpha_after[s, wg])
        face = (h.prim >= 0) & (h.surface < 0) & ~h.detector & found
        inside = face & (np.einsum("ij,ij->i", d, h.normal) > 0.0)  # h.normal: the triangle's outward normal
        alpha[inside] = self._alpha_solid[h.tag[inside], wl[inside]]
        return np.exp(-alpha * np.where(found, np.maximum(h.t, 0.0), 0.0))

    def _interface(self, surf, nrm, d, w, wl, ghosts: bool, u):
        """Refract/reflect rays (m,) at optical surfaces `surf` (positions in scene.optical) with
        the analytic normals nrm (m, 3) of their hits; u (m,) uniforms for the Fresnel branch
        (None: always transmit)."""
        r = np.empty(len(d))
        cos_dn = np.einsum("ij,ij->i", d, nrm)
        forward = cos_dn >= 0.0
        n1 = np.where(forward, self._n_before[surf, wl], self._n_after[surf, wl])
        n2 = np.where(forward, self._n_after[surf, wl], self._n_before[surf, wl])
        t_dir, tir, cos_i, _ = refract(d, nrm, n1 / n2)
        for k in np.unique(surf):
            sel = surf == k
            r[sel] = reflectance(n1[sel], n2[sel], cos_i[sel], self.scene.optical[k].coating,
                                 self._wavelengths[wl[sel]])
        r = np.where(tir, 1.0, np.clip(r, 0.0, 1.0))
        mirror = reflect(d, nrm)
        if ghosts:
            u = np.ones(len(d)) if u is None else u
            bounce = tir | (u < r)
            new_d = np.where(bounce[:, None], mirror, t_dir)
            refl = (bounce & ~tir).astype(np.int32)
        else:
            new_d = t_dir  # the TIR lanes already hold the mirror direction
            refl = np.zeros(len(d), np.int32)
        at_mirror = self._mirror[surf]  # a mirror reflects every ray, weighted by its R (no branch)
        new_w = np.where(at_mirror, w * self._mirror_r[surf], w if ghosts else w * np.where(tir, 1.0, 1.0 - r))
        return np.where(at_mirror[:, None], mirror, new_d), new_w, np.where(at_mirror, 0, refl)


def _left_normal(origin_normal, n: int) -> np.ndarray:
    """(n, 3) float64 normal of the face each ray leaves, zeros where none or not finite."""
    if origin_normal is None:
        return np.zeros((n, 3))
    nrm = np.asarray(origin_normal, np.float64)
    return np.where(np.all(np.isfinite(nrm), axis=1, keepdims=True), nrm, 0.0)


def _newton_asphere(prof, o, d, t0, steps: int = 40, tol: float = 1e-12):
    """Ray parameter of the crossing with an aspheric profile near t0 (n,), by Newton on
    f(t) = z(t) − sag(r(t)); inf where it does not converge (treated as a fake hit)."""
    t = np.where(np.isfinite(t0), t0, 0.0).astype(np.float64)
    ok = np.isfinite(t0)
    for _ in range(steps):
        p = o + t[:, None] * d
        r2 = p[:, 0] ** 2 + p[:, 1] ** 2
        f = p[:, 2] - prof.sag(r2)
        df = d[:, 2] - prof.slope(r2) * (p[:, 0] * d[:, 0] + p[:, 1] * d[:, 1])
        good = np.isfinite(f) & np.isfinite(df) & (np.abs(df) > 1e-12)
        step = np.where(good, f / np.where(good, df, 1.0), 0.0)
        ok &= good
        t = t - step
        if np.all(np.abs(step[ok]) < tol):
            break
    p = o + t[:, None] * d
    resid = np.abs(p[:, 2] - prof.sag(p[:, 0] ** 2 + p[:, 1] ** 2))
    return np.where(ok & np.isfinite(resid) & (resid < 1e-9), t, np.inf)


__all__ = ["Tracer", "Hits", "Events", "GONE", "FACE", "DETECTOR", "FRESNEL_DIM", "MIRROR_SCATTER_DIM",
           "MIRROR_SCATTER_MIN_SHARE"]
