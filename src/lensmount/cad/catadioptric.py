"""Layout of a lens with mirrors: cells in a straight barrel, spiders for the cells in the beam.

A folded path crosses the same z more than once, so "the beam envelope at z" (the largest
radius of any ray there, `optics.apertures.beam_envelope`) only sizes the barrel. What may
stand where is decided on the rays themselves, as polylines in (r, z):

* Elements. Physical surfaces are the prescription's surfaces with the return passes
  folded onto the surface they retrace (a Mangin's front face, met twice). Glass between
  two physical surfaces is a lens element (`LensElement`, or `MirrorElement` when one face
  reflects or a central hole is needed); a mirror in air is a front-surface mirror blank
  a third of its radius thick on the side away from the light. Glass pieces sharing a
  surface, or whose edges leave no room for a lip between them, are held as one unit.
* Cells. Each unit sits in a ring (`Cell`) with a front lip and a back support, everywhere
  `seats.clearance_mm` off the glass; the lips stand at the clear semi-diameter plus the
  contact margin on an optical face, at half the radius on a mirror blank's flat back.
* Outer and central units. A unit no ray passes outside of, and no other element's body,
  is an *outer* unit: its ring runs out to the barrel. The others stand in the beam (a
  Cassegrain's secondary, a relay in its shadow). Neighbouring lens units are joined by a
  tube where the light between them stays inside its bore, so a relay hangs on the cell
  that reaches the barrel; a central unit with no such join stands on a spider
  (`SpiderCell`: three thin vanes to the barrel, the only part not of revolution).
* Obscuration. A ray that on its way to the first mirror crosses a central unit's ring (not
  interacting with it) is obscured by design, as the secondary's shadow is. Where the light
  the mirrors return would still meet a central part, the first central cell on the way in is
  widened into a baffle until it obscures those rays (the designer's central obscuration). Every other ray of the
  full field must pass every part (spider vanes excepted): `BeamPaths.check`, which the
  profile checks run in place of the envelope test. An element that another pass of the
  light crosses gets a central hole as wide as that light plus the aperture margin.

No hood, vanes or detector housing are built for a catadioptric lens yet (a note says so):
the barrel is the light tube and the detector stands where the scene puts it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from matplotlib.path import Path as MplPath

from lensmount.cad.plan import Envelope, Layout, PartPlan
from lensmount.design.mount import MountSpec
from lensmount.errors import GeometryError
from lensmount.optics.apertures import ENVELOPE_FIELDS, _beam, _field_samples
from lensmount.optics.prescription import Prescription
from lensmount.optics.realrays import pupil_rings
from lensmount.templates.barrel import Barrel
from lensmount.templates.cell import Cell, SpiderCell
from lensmount.templates.lens_element import LensElement, OpticalFace
from lensmount.templates.mirror import MirrorElement

BLANK_RATIO = 1.0 / 3.0   # a mirror blank's thickness over its radius (diameter : thickness = 6 : 1)
SPIDER_VANES = 3
_SAMPLE_MM = 0.25         # z step of the ray samples for the beam check
_BEAM_TOL_MM = 1e-3


def physical_surfaces(p: Prescription) -> list[int]:
    """For each surface, the first surface with the same vertex and shape (a return pass)."""
    zv, out = p.vertex_z, []
    for i, s in enumerate(p.surfaces):
        twin = next((j for j in range(i) if abs(zv[j] - zv[i]) < 1e-9 and not s.mirror
                     and not p.surfaces[j].mirror and p.surfaces[j].curvature == s.curvature
                     and p.surfaces[j].conic == s.conic and p.surfaces[j].aspheric == s.aspheric
                     and p.surfaces[j].qtype == s.qtype), i)
        out.append(twin)
    return out


@dataclass
class _Unit:
    """Elements held together: names, templates, physical surfaces, radius."""

    pieces: list[tuple[int, int]]            # (front surface, back surface) per glass piece; (i, -1) a blank
    radius: float
    surfaces: set[int]
    mirror: bool
    inner: bool = False
    hole: float = 0.0
    names: list[str] = field(default_factory=list)
    templates: list = field(default_factory=list)
    z0: float = 0.0                           # the cell's z range
    z1: float = 0.0
    cell: Cell | SpiderCell | None = None
    cell_name: str = ""
    lips: list = field(default_factory=list)     # front and back lip thickness
    r_out: float = 0.0                             # the cell's outside radius
    hf: float = 0.0                                # lip bores, front and back
    hb: float = 0.0
    tube: tuple | None = None                      # (r_in, r_out, z0, z1) of the tube to the unit behind
    holder: _Unit | None = None                    # the unit that tube ends on


class BeamPaths:
    """The rays of the full field as (r, z) polylines, each segment knowing the physical
    surfaces it runs between; `check` tests mechanical profiles against the unobscured ones."""

    def __init__(self, p: Prescription, phys: list[int], z_front: float):
        fields = _field_samples(p, min(ENVELOPE_FIELDS, 5))
        pupil = pupil_rings(12, 24, half=False)
        polys = []
        for rays in _beam(p, fields, pupil, clip=True):
            ok = ~rays.vignetted   # the file's own apertures stop the others (the designer's vignetting)
            o, d = rays.origins[ok], rays.start_directions[ok]
            s = (z_front - o[:, 2]) / np.where(np.abs(d[:, 2]) > 1e-12, d[:, 2], 1e-12)
            start = o + np.minimum(s, 0.0)[:, None] * d
            polys.append(np.concatenate([start[None], rays.points[:, ok]], axis=0))
        self.points = np.concatenate(polys, axis=1) if polys else np.zeros((len(p.surfaces) + 2, 0, 3))
        n = len(p.surfaces)
        # segment k runs from node k-1 to node k: node -1 the start, node n the image plane
        self.ends = [(-1 if k == 0 else phys[k - 1], phys[k] if k < n else -2) for k in range(n + 1)]
        self.obscured = np.zeros(self.points.shape[1], bool)
        self.first_mirror = next(i for i, s in enumerate(p.surfaces) if s.mirror)   # segment k ends on surface k

    def crossing(self, k: int, za: float, zb: float):
        """Rays' segment k over z in [za, zb]: (crosses (N,), r_min (N,), r_max (N,))."""
        p0, p1 = self.points[k], self.points[k + 1]
        z0, z1 = p0[:, 2], p1[:, 2]
        dz = np.where(np.abs(z1 - z0) > 1e-12, z1 - z0, 1e-12)
        ta = np.clip((za - z0) / dz, 0.0, 1.0)
        tb = np.clip((zb - z0) / dz, 0.0, 1.0)
        lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
        crosses = (np.maximum(z0, z1) >= za) & (np.minimum(z0, z1) <= zb)
        a, b = p0[:, :2], p1[:, :2] - p0[:, :2]
        t_min = np.clip(-np.einsum("ij,ij->i", a, b) / np.maximum(np.einsum("ij,ij->i", b, b), 1e-300), lo, hi)
        r_at = lambda t: np.hypot(*(a + t[:, None] * b).T)  # noqa: E731
        return crosses, r_at(t_min), np.maximum(r_at(lo), r_at(hi))

    def passing(self, surfaces: set[int], za: float, zb: float, unobscured: bool, leg: str = "all"):
        """(r_min, r_max) over the segments that cross [za, zb] without meeting `surfaces`, per ray
        (inf, -inf where none); leg: "incoming" (up to the first mirror), "returning" (after it) or "all"."""
        n = self.points.shape[1]
        r_lo, r_hi = np.full(n, np.inf), np.full(n, -np.inf)
        for k, (a, b) in enumerate(self.ends):
            if a in surfaces or b in surfaces or (leg == "incoming" and k > self.first_mirror) \
                    or (leg == "returning" and k <= self.first_mirror):
                continue
            c, lo, hi = self.crossing(k, za, zb)
            if unobscured:
                c &= ~self.obscured
            r_lo = np.where(c, np.minimum(r_lo, lo), r_lo)
            r_hi = np.where(c, np.maximum(r_hi, hi), r_hi)
        return r_lo, r_hi

    def meeting(self, surface: int, za: float, zb: float) -> float:
        """Largest radius over z in [za, zb] of the light arriving at or leaving physical `surface`."""
        r = -np.inf
        for k, (a, b) in enumerate(self.ends):
            if surface in (a, b):
                c, _, hi = self.crossing(k, za, zb)
                if c.any():
                    r = max(r, float(hi[c].max()))
        return r

    def between(self, first: set[int], second: set[int], za: float, zb: float) -> float:
        """Largest radius over z in [za, zb] of the light going from `first` to `second` (or back)."""
        r = 0.0
        for k, (a, b) in enumerate(self.ends):
            if (a in first and b in second) or (a in second and b in first):
                c, _, hi = self.crossing(k, za, zb)
                if c.any():
                    r = max(r, float(hi[c].max()))
        return r

    def radius_on(self, surfaces: set[int]) -> float:
        """Smallest radius at which an unobscured ray meets one of the physical `surfaces`."""
        keep = ~self.obscured
        r = [np.hypot(*self.points[k + 1][keep][:, :2].T) for k, (_, b) in enumerate(self.ends) if b in surfaces]
        r = np.concatenate(r) if r else np.zeros(0)
        return float(r.min()) if r.size else np.inf

    def check(self, layout, outlines: dict[str, np.ndarray]) -> None:
        """No unobscured ray passes through a mechanical part (spider vanes are not in the outlines)."""
        keep = ~self.obscured
        pts = self.points[:, keep]
        for plan in layout.parts:
            if plan.kind in ("lens", "mirror") or plan.name not in outlines:
                continue
            poly = outlines[plan.name]
            path = MplPath(poly)
            (r_min, z_min), (r_max, z_max) = poly.min(0), poly.max(0)
            zq = np.linspace(z_min, z_max, int(np.ceil((z_max - z_min) / _SAMPLE_MM)) + 2)[:, None]
            for k in range(len(pts) - 1):
                p0, p1 = pts[k], pts[k + 1]
                dz = p1[:, 2] - p0[:, 2]
                t = (zq - p0[:, 2]) / np.where(np.abs(dz) > 1e-12, dz, 1e-12)     # (m, N): the part's z planes
                on = (t >= 0.0) & (t <= 1.0) & (np.abs(dz) > 1e-12)
                if not on.any():
                    continue
                x = p0[:, 0] + t * (p1[:, 0] - p0[:, 0])
                y = p0[:, 1] + t * (p1[:, 1] - p0[:, 1])
                rz = np.stack([np.hypot(x, y)[on], np.broadcast_to(zq, t.shape)[on]], axis=-1)
                near = (rz[:, 0] >= r_min - 1) & (rz[:, 0] <= r_max + 1)
                if not near.any():
                    continue
                inside = path.contains_points(rz[near], radius=-_BEAM_TOL_MM)
                if inside.any():
                    r, z = rz[near][inside][0]
                    raise GeometryError(
                        f"{plan.name} stands in the light of the full field at r = {r:.3f} mm, z = {z:.3f} mm "
                        f"(segment {k} of the folded path, a ray the central obscuration does not stop)",
                        field=plan.kind, valid="larger bores or holes, or a smaller edge allowance")


def plan_catadioptric(p: Prescription, spec: MountSpec) -> Layout:
    """The Layout of a lens with mirrors (module docstring). Raises GeometryError."""
    mount = _CatadioptricPlanner(p, spec)
    mount.units()
    mount.fit_units()
    mount.lips()
    mount.beam_paths()
    mount.cells()
    mount.central_units()
    mount.holes()
    return mount.layout()


class _CatadioptricPlanner:
    """The stages of `plan_catadioptric` and what they share: the lens (its physical surfaces), mount.toml's
    settings, the units being sized, the folded beam and the barrel's bore."""

    def __init__(self, p: Prescription, spec: MountSpec):
        self.p, self.spec = p, spec
        self.surf, self.zv, self.travel = p.surfaces, p.vertex_z, p.travel
        self.phys = physical_surfaces(p)
        self.clear = [float(s.clear_semi_diameter) for s in self.surf]
        self.edge, self.min_t = spec.lens_edge, spec.checks.min_thickness_mm
        self.c_glass, self.c_bore, self.c_sp = (spec.seats.clearance_mm, spec.barrel.radial_clearance_mm,
                                                spec.spacers.radial_clearance_mm)
        self.lip, self.margin = spec.barrel.lip_mm, spec.spacers.aperture_margin_mm
        self.cm = self.edge.contact_margin_mm
        self.cell_wall = 2 * self.min_t
        self.notes = ["catadioptric lens: no hood, vanes or detector housing are built (the barrel is the light tube)"]
        self.all_units: list[_Unit] = []
        self.beam: BeamPaths | None = None
        self.env: Envelope | None = None
        self.r_bore = 0.0

    def _face(self, i: int) -> OpticalFace:
        s = self.surf[i]
        return OpticalFace.of(i, float(self.zv[i]), s)

    def _clear_of(self, j: int) -> float:   # a physical surface's clear semi-diameter over all its passes
        return max(self.clear[i] for i in range(len(self.surf)) if self.phys[i] == j)

    def _mech_of(self, j: int) -> float:
        mech = [self.surf[i].mechanical_semi_diameter or 0.0 for i in range(len(self.surf)) if self.phys[i] == j]
        return max([self._clear_of(j) + self.edge.allowance_mm] + mech)

    def _side(self, i: int) -> int:   # the direction light arrives at surface i from
        return 1 if i == 0 else self.travel[i - 1]

    def units(self) -> None:
        """Glass pieces (glass between two physical surfaces) and front-surface mirror blanks, pieces that
        share a surface held as one unit, each at the largest mechanical semi-diameter of its surfaces
        (clear + [lens_edge] allowance_mm where the file gives none)."""
        surf, zv, phys, mech_of = self.surf, self.zv, self.phys, self._mech_of
        pieces = set()
        for i, s in enumerate(surf[:-1]):
            if not s.is_air_after and phys[i] != phys[i + 1]:
                a, b = sorted((phys[i], phys[i + 1]), key=lambda j: zv[j])
                pieces.add((a, b))
        units = self.all_units
        for a, b in sorted(pieces, key=lambda ab: zv[ab[0]]):
            joined = [u for u in units if u.pieces[0][1] != -1 and ({a, b} & u.surfaces)]
            if joined:
                u = joined[0]
                u.pieces.append((a, b))
                u.surfaces |= {a, b}
                u.radius = max(u.radius, mech_of(a), mech_of(b))
                u.mirror |= surf[a].mirror or surf[b].mirror
            else:
                units.append(_Unit([(a, b)], max(mech_of(a), mech_of(b)), {a, b}, surf[a].mirror or surf[b].mirror))
        for i, s in enumerate(surf):
            if s.mirror and s.is_air_after and self.p.material_before(i).upper() == "AIR":
                units.append(_Unit([(i, -1)], mech_of(i), {i}, True))
        if not units:
            raise GeometryError("the prescription has neither glass nor mirrors: nothing to mount", field="surfaces")

    def _build_templates(self, u: _Unit) -> None:
        face, clear, clear_of, surf = self._face, self.clear, self._clear_of, self.surf
        u.templates = []
        R, h = u.radius, u.hole
        for a, b in u.pieces:
            if b == -1:   # a front-surface mirror blank on the side away from the light
                rs = np.linspace(h, R, 65)
                zs = face(a).z(rs)
                t = max(min(BLANK_RATIO * R, 0.4 * self._room(u, a)), 2 * self.min_t)
                if self._side(a) > 0:
                    el = MirrorElement(face(a), None, R, h, front_coated=clear[a], back_z_flat=float(zs.max()) + t)
                else:
                    el = MirrorElement(None, face(a), R, h, back_coated=clear[a], front_z_flat=float(zs.min()) - t)
            elif u.mirror or h > 0:
                el = MirrorElement(face(a), face(b), R, h, front_coated=clear_of(a) if surf[a].mirror else None,
                                   back_coated=clear_of(b) if surf[b].mirror else None)
            else:
                el = LensElement(face(a), face(b), R)
            u.templates.append(el)

    @staticmethod
    def _extent(u: _Unit):
        rs = np.linspace(u.hole, u.radius, 65)
        return (min(float(np.min(t.front_z(rs))) for t in u.templates),
                max(float(np.max(t.back_z(rs))) for t in u.templates))

    def _room(self, u: _Unit, a: int) -> float:
        """Axial room behind mirror surface a (away from the light) to the nearest glass."""
        side = self._side(a)
        zs = self._face(a).z(np.linspace(u.hole, u.radius, 65))
        edge = float(zs.max()) if side > 0 else float(zs.min())
        gaps = [(w_lo - edge) if side > 0 else (edge - w_hi) for w in self.all_units if w is not u and w.templates
                for w_lo, w_hi in [self._extent(w)]]
        gaps = [g for g in gaps if g > 0]
        return min(gaps) if gaps else np.inf

    def _fit_radius(self, u: _Unit) -> None:
        """Cut the unit's radius back where a glass piece's edge would be thinner than min_t."""
        min_t = self.min_t
        floor = max(self._clear_of(j) for j in u.surfaces) + self.cm + min_t
        while True:
            self._build_templates(u)
            thin = [t for t, (a, b) in zip(u.templates, u.pieces) if b != -1
                    and float(t.back_z(u.radius) - t.front_z(u.radius)) < min_t]
            if not thin or u.radius - 0.05 < floor:
                break
            u.radius -= 0.05

    def fit_units(self) -> None:
        """Each unit's templates, its radius cut back where an edge would be thinner than [checks]
        min_thickness_mm; units whose edges leave no room for a lip between them are held as one."""
        extent, units = self._extent, self.all_units
        for u in sorted(units, key=lambda w: w.pieces[0][1] == -1):   # glass first: blanks fit the room it leaves
            self._fit_radius(u)
        units.sort(key=lambda u: extent(u)[0])
        merged: list[_Unit] = []
        for u in units:
            if merged and not u.mirror and not merged[-1].mirror:
                prev = merged[-1]
                gap = extent(u)[0] - extent(prev)[1]
                if gap < 2 * self.min_t + 3 * self.c_glass:
                    prev.pieces += u.pieces
                    prev.surfaces |= u.surfaces
                    prev.radius = max(prev.radius, u.radius)
                    self._fit_radius(prev)
                    continue
            merged.append(u)
        self.all_units = merged

    def lips(self) -> None:
        """Each cell's front and back lip: [barrel] lip_mm thick, or half the gap to the neighbour's glass
        (less [seats] clearance_mm), at least [checks] min_thickness_mm."""
        extent, units, c_glass = self._extent, self.all_units, self.c_glass
        for u in units:
            u.lips = [self.lip, self.lip]
        for prev in units:   # with the nearest unit wholly behind it (a relay nested in a hole has none)
            behind = [u for u in units if extent(u)[0] >= extent(prev)[1]]
            if behind:
                u = min(behind, key=lambda w: extent(w)[0])
                share = 0.5 * (extent(u)[0] - extent(prev)[1]) - 1.5 * c_glass
                prev.lips[1] = min(prev.lips[1], share)
                u.lips[0] = min(u.lips[0], share)
        for u in units:
            if min(u.lips) < self.min_t:
                raise GeometryError(f"surfaces {'/'.join(str(j + 1) for j in sorted(u.surfaces))}: no room for a "
                                    f"cell lip {self.min_t} mm thick next to the neighbouring element",
                                    field="checks.min_thickness_mm", valid="a thinner minimum wall or a larger air gap")

    def beam_paths(self) -> None:
        """The folded path's rays (what may stand where) and the beam envelope (the barrel's bore only)."""
        extent, units, p, lip = self._extent, self.all_units, self.p, self.lip
        z_lo = min(extent(u)[0] for u in units) - 4 * lip - 10.0
        self.beam = BeamPaths(p, self.phys, z_lo)
        z_hi = max(p.image_z, max(extent(u)[1] for u in units)) + lip
        self.env = Envelope(p, z_lo, z_hi, step=max(0.25, (z_hi - z_lo) / 200))

    def _lip_radius(self, t, front: bool, R: float, h: float) -> float:
        f = t.front if front else t.back
        if f is None:   # a blank's flat back: a ring support at half the radius
            return max(0.5 * R, h + self.margin + self.min_t)
        z = float(f.z(R))
        za, zb = (z - 2 * self.lip, z) if front else (z, z + 2 * self.lip)
        beam_near = self.beam.meeting(self.phys[f.index], za, zb) + self.margin
        return min(max(self._clear_of(f.index) + self.cm, beam_near), R + self.c_bore)

    def _cell_outline(self, u: _Unit, r_out: float):
        c_glass, c_bore = self.c_glass, self.c_bore
        first, last = u.templates[0], u.templates[-1]
        R = u.radius
        hf, hb = self._lip_radius(first, True, R, u.hole), self._lip_radius(last, False, R, u.hole)
        rf, rb = np.linspace(hf, R, 65), np.linspace(hb, R, 65)
        zf = float(np.min(first.front_z(rf))) - c_glass
        zb = float(np.max(last.back_z(rb))) + c_glass
        # a front-surface mirror's coated face gets no lip: the light it returns leaves at any
        # height, so the ring stops level with the blank's edge there (the back support holds it)
        lf, lb = u.lips
        if u.pieces[0][1] == -1 and first.front is not None:
            hf, zf, lf = R + c_bore, float(first.front_z(R)), 0.0
        if u.pieces[-1][1] == -1 and last.back is not None:
            hb, zb, lb = R + c_bore, float(last.back_z(R)), 0.0
        u.z0, u.z1, u.hf, u.hb, u.r_out = zf - lf, zb + lb, hf, hb, r_out
        return ((hf, zf - lf), (r_out, zf - lf), (r_out, zb + lb), (hb, zb + lb), (hb, zb),
                (R + c_bore, zb), (R + c_bore, zf), (hf, zf))

    def _obscure(self) -> None:
        # only on the way in: a central part that stops light the mirrors return is in the beam
        beam = self.beam
        beam.obscured[:] = False
        for u in self.all_units:
            if u.inner:
                c_lo, _ = beam.passing(u.surfaces, u.z0, u.z1, unobscured=False, leg="incoming")
                beam.obscured |= np.isfinite(c_lo) & (c_lo < u.r_out)

    def cells(self) -> None:
        """The barrel's bore (clear of every unit and of the beam by [spacers] aperture_margin_mm) and a cell
        per unit reaching it; the units the light passes outside of, or another element's body, are central."""
        extent, units = self._extent, self.all_units
        self.r_bore = max(max(u.radius for u in units) + self.c_bore + self.min_t + self.c_sp,
                          float(self.env.r.max()) + self.margin)
        for u in units:
            self._cell_outline(u, self.r_bore)
        for u in units:
            r_lo, r_hi = self.beam.passing(u.surfaces, u.z0, u.z1, unobscured=False)
            body = any(w is not u and extent(w)[0] < extent(u)[1] and extent(w)[1] > extent(u)[0]
                       and w.radius > u.radius for w in units)
            u.inner = bool(np.any(r_hi > u.radius)) or body

    def central_units(self) -> None:
        """The central units' cells, a wall of 2 × [checks] min_thickness_mm round them, inside the light
        that passes them; a central lens unit on a tube from the lens unit behind it where the light
        between them stays inside the tube; the first central cell widened until it obscures what the
        mirrors return toward a central part."""
        extent, units, beam, margin, c_bore, cell_wall = (self._extent, self.all_units, self.beam, self.margin,
                                                          self.c_bore, self.cell_wall)
        for u in units:
            if u.inner:
                self._cell_outline(u, u.radius + c_bore + cell_wall)
        self._obscure()
        for u in units:   # a central unit's edge and cell stay inside the light that passes it
            if not u.inner:
                continue
            r_lo, _ = beam.passing(u.surfaces, u.z0, u.z1, unobscured=True, leg="returning")
            fits = float(r_lo.min()) - c_bore - cell_wall - margin
            if fits < u.radius:
                u.radius = max(fits, max(self._clear_of(j) for j in u.surfaces) + self.cm + self.min_t)
                self._fit_radius(u)
                self._cell_outline(u, u.radius + c_bore + cell_wall)
        self._obscure()
        # a central lens unit hangs on a tube from the lens unit behind it where the light between
        # them stays inside the tube's bore (a relay cantilevered from the cell that reaches the barrel)
        for u in sorted(units, key=lambda x: -extent(x)[0]):   # from the back: the unit behind is final
            if not u.inner or u.mirror:
                continue
            behind = [w for w in units if not w.mirror and extent(w)[0] >= extent(u)[1]]
            if not behind:
                continue
            w = min(behind, key=lambda x: extent(x)[0])
            r_in = max(u.hb, w.hf, beam.between(u.surfaces, w.surfaces, u.z1, w.z0) + margin)
            r_out = max(u.r_out, r_in + cell_wall)
            if w.inner:
                r_out = min(r_out, w.r_out)
            if r_out - r_in >= self.min_t:
                self._cell_outline(u, r_out)
                u.tube, u.holder = (r_in, r_out, u.z1, w.z0), w
        self._obscure()
        # The light the mirrors return passes the central parts on its way to the image; where it
        # would meet one, the first central cell on the way in (the secondary's) is widened into a
        # baffle that obscures those rays, as a designer sizes a Cassegrain's central obscuration.
        inner = [u for u in units if u.inner]
        if inner:
            front = min(inner, key=lambda u: u.z0)
            for _ in range(20):
                clash = np.zeros_like(beam.obscured)
                for u in inner:
                    spans = [(u.surfaces, u.r_out, u.z0, u.z1)]
                    if u.tube:
                        spans.append((u.surfaces | u.holder.surfaces, u.tube[1], u.tube[2], u.tube[3]))
                    for surfaces, r_out, za, zb in spans:
                        r_lo, _ = beam.passing(surfaces, za, zb, unobscured=True, leg="returning")
                        clash |= r_lo < r_out + margin
                if not clash.any():
                    break
                r_in, _ = beam.passing(front.surfaces, front.z0, front.z1, unobscured=False, leg="incoming")
                grown = float(r_in[clash & np.isfinite(r_in)].max(initial=front.r_out)) + _BEAM_TOL_MM
                if grown <= front.r_out + _BEAM_TOL_MM or grown >= self.r_bore - self.min_t:
                    break   # nothing more to obscure from there: the beam check says where the light meets what
                self._cell_outline(front, grown)
                self._obscure()

    def holes(self) -> None:
        """A central hole in each outer unit that another pass of the light, or a central part, goes
        through: that light plus [spacers] aperture_margin_mm."""
        units = self.all_units
        for u in units:
            if u.inner:
                continue
            za, zb = self._extent(u)
            _, r_hi = self.beam.passing(u.surfaces, za, zb, unobscured=True)
            through = [float(r_hi[np.isfinite(r_hi)].max())] if np.isfinite(r_hi).any() else []
            through += [w.r_out for w in units if w.inner and w.z0 < zb and w.z1 > za]
            through += [w.tube[1] for w in units if w.tube and w.holder is not u and w.tube[2] < zb and w.tube[3] > za]
            if through:
                u.hole = max(through) + self.margin
                self._build_templates(u)
                self._cell_outline(u, self.r_bore)
                used = self.beam.radius_on(u.surfaces)
                if used < u.hole:
                    raise GeometryError(
                        f"{'/'.join(str(j + 1) for j in sorted(u.surfaces))}: the central hole the returning light "
                        f"needs ({u.hole:.3f} mm) reaches into the zone the unobscured light uses (from {used:.3f} mm)",
                        field="spacers.aperture_margin_mm", valid="a smaller aperture margin or contact margin")

    def layout(self) -> Layout:
        """The parts: lenses and mirrors numbered along z, a cell per unit (a ring to the barrel, a cell held
        by a tube, or a spider of [vanes] thickness_mm), the tubes, and the straight barrel, [barrel] lip_mm
        beyond the first and last cells, [barrel] wall_mm thick."""
        spec, units, edge, cell_outline, r_bore = self.spec, self.all_units, self.edge, self._cell_outline, self.r_bore
        extent = self._extent
        # a unit that hangs on a tube from one that hangs on the barrel needs no spider
        held = {id(u) for u in units if not u.inner}
        for _ in units:
            held |= {id(u) for u in units if u.holder is not None and id(u.holder) in held}
        parts: list = []
        n_lens = n_mirror = 0
        for u in units:
            u.names = []
            for (a, b), t in zip(u.pieces, u.templates):
                if b == -1:
                    n_mirror += 1
                    u.names.append(f"mirror-{n_mirror}")
                    parts.append(PartPlan(u.names[-1], "mirror", spec.finish_of(u.names[-1], edge.finish), t))
                else:
                    n_lens += 1
                    u.names.append(f"lens-{n_lens}")
                    parts.append(PartPlan(u.names[-1], "lens", spec.finish_of(u.names[-1], edge.finish), t))
        for k, u in enumerate(units, start=1):
            u.cell_name = f"cell-{k}"
            if not u.inner:
                u.cell = Cell(cell_outline(u, r_bore - self.c_sp))
            elif id(u) in held:
                u.cell = Cell(cell_outline(u, u.r_out))
            else:
                outline = cell_outline(u, u.r_out)
                clash = [w.names[0] for w in units if w is not u and extent(w)[0] < u.z1 and extent(w)[1] > u.z0
                         and w.radius > u.r_out]
                if clash:
                    raise GeometryError(f"{u.cell_name} ({', '.join(u.names)}) stands in the beam and its spider "
                                        f"to the barrel would cut {clash[0]}", field="lens_edge.allowance_mm",
                                        valid="a lens whose central elements a tube can join to one behind them")
                u.cell = SpiderCell(outline, SPIDER_VANES, spec.vanes.thickness_mm, r_bore, u.z0, u.z1)
                self.notes.append(f"{u.cell_name} ({', '.join(u.names)}) stands in the beam on {SPIDER_VANES} vanes "
                                  f"{spec.vanes.thickness_mm} mm thick")
            parts.append(PartPlan(u.cell_name, "cell", spec.finish_of(u.cell_name, spec.retainer.finish), u.cell))
            if u.tube:
                r_in, r_out, z0, z1 = u.tube
                name = f"tube-{k}"
                parts.append(PartPlan(name, "spacer", spec.finish_of(name, spec.spacers.finish),
                                      Cell(((r_in, z0), (r_out, z0), (r_out, z1), (r_in, z1)))))
        z_front = min(u.z0 for u in units) - self.lip
        z_back = max(u.z1 for u in units) + self.lip
        barrel = Barrel(((r_bore, z_front), (r_bore, z_back)), float(r_bore + spec.barrel.wall_mm))
        parts.insert(0, PartPlan("barrel", "barrel", spec.finish_of("barrel", spec.barrel.finish), barrel))
        layout = Layout(self.p, parts, [], self.env, self.notes)
        layout.beam = self.beam
        return layout


__all__ = ["plan_catadioptric", "physical_surfaces", "BeamPaths"]
