"""Layout: prescription + MountSpec → every part's template, placed in the assembly frame.

Pure numbers, no CAD kernel: the axial stack (retainer, lens groups, spacers,
diaphragm, shoulders), the barrel's stepped bore, hood, vanes and housing. The
beam envelope (real rays of the full field, every wavelength, full pupil) sets the
vane bores. Geometry rules, all in the (r, z) half plane of the solids of revolution:

* A lens group's mechanical radius R is the largest of its surfaces' mechanical
  semi-diameters (clear semi-diameter + edge allowance when the file gives none);
  its bore is R + radial clearance.
* Every contact (spacer, retainer, shoulder) touches an optical surface at the
  contact height h = clear semi-diameter + contact margin, with an end face cone
  whose slope keeps it off the glass everywhere else (`cad.seats.contact_slope`).
* The bore steps where the glass outside the spacer's radius ends, so no part
  overlaps another; `checks` verifies it on the final profiles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import lensmount.cad.kinds.hood  # noqa: F401  (the built-in part kinds register as they load, in this order)
import lensmount.cad.kinds.housing  # noqa: F401
from lensmount.cad.catadioptric import plan_catadioptric
from lensmount.cad.lens_groups import ends_inside, face_beyond_reach, group_rim, lens_group, seat_of_group, thin_plate
from lensmount.cad.plan import Contact, Envelope, Layout, PartPlan
from lensmount.cad.seats import (BEAM_CLEAR_MM, EPS_SLOPE, check_ring_wall, contact_slope, diaphragm_spacer_ends,
                                 glass_seat_bore, radii_to_rim, ring_opening, stop_diaphragm)
from lensmount.cad.stages import Mount, place_kinds
from lensmount.design.mount import MountSpec
from lensmount.errors import GeometryError
from lensmount.optics.apertures import with_clear_semi_diameters
from lensmount.optics.prescription import Prescription
from lensmount.templates.barrel import Barrel
from lensmount.templates.diaphragm import Diaphragm
from lensmount.templates.lens_element import LensElement, OpticalFace
from lensmount.templates.retainer import Retainer
from lensmount.templates.spacer import Spacer

APERTURE_SAMPLES = 65  # points from the axis to the rim of the entrance aperture (vane sight lines)


def _size_keys(part: str) -> list[str]:
    """The mount.toml keys that set how much of an air gap a part takes along the axis."""
    if part == "diaphragm":
        return ["diaphragm.thickness_mm"]
    if part.startswith("retainer"):
        return ["retainer.thickness_mm"]
    if part.startswith("vane"):
        return ["vanes.thickness_mm"]
    return ["lens_edge.contact_margin_mm"]  # a lens: where its seat touches


def plan(prescription: Prescription, spec: MountSpec) -> Layout:
    """Place every part, front to back. Raises GeometryError for a mount that cannot be built."""
    p = prescription
    if any(s.clear_semi_diameter is None for s in p.surfaces):
        p = with_clear_semi_diameters(p)
    if p.has_mirrors:
        return plan_catadioptric(p, spec)
    mount = _MountPlanner(p, spec)
    mount.lens_groups()
    mount.beam()
    z_front = mount.front_seat()
    mount.gaps()
    z_back = mount.rear_seat()
    return mount.part_kinds(z_front, z_back, mount.barrel())


@dataclass
class _Gap:
    """The air gap between two lens groups: the elements the seats touch (A in front of the gap, B behind
    it; a stepped group's GroupOutline), their outer surfaces ia, ib, the surfaces sa, sb and heights
    hA, hB where the seats touch (ia, ib unless stepped), the groups' rims and bores."""

    A: PartPlan
    B: PartPlan
    ia: int
    ib: int
    sa: int
    hA: float
    sb: int
    hB: float
    RA: float
    RB: float
    bore_a: float
    bore_b: float
    element_no: int  # B's group's first element: the number its seat has in [seats] element


class _MountPlanner:
    """The stages of `plan` and what they share: the lens, mount.toml's settings, and what is placed so far
    (the barrel's bore front to back, parts, contacts on the glass, notes for the user)."""

    def __init__(self, p: Prescription, spec: MountSpec):
        self.p, self.spec = p, spec
        self.clear = [float(s.clear_semi_diameter) for s in p.surfaces]
        edge = spec.lens_edge
        self.chamfer = edge.chamfer_mm if edge.style == "chamfered" else 0.0
        self.cm, self.tangent = edge.contact_margin_mm, spec.seats.contact == "tangent"
        self.wedge, self.c_glass = float(np.tan(np.radians(spec.seats.wedge_deg))), spec.seats.clearance_mm
        self.c_bore, self.c_sp = spec.barrel.radial_clearance_mm, spec.spacers.radial_clearance_mm
        self.min_t = spec.checks.min_thickness_mm
        self.stop = p.stop_index
        self.groups = p.lens_groups()
        self.lens_parts: list[list[PartPlan]] = []
        self.seats_of_groups: list = []   # per group: (front, back) seats, seat_of_group
        self.radii: list[float] = []
        self.bores: list[float] = []
        self.env: Envelope | None = None
        self.parts: list[PartPlan] = []   # the diaphragm; the barrel goes first once its bore is known
        self.retainers: list[PartPlan] = []
        self.spacers: list[PartPlan] = []
        self.contacts: list[Contact] = []
        self.notes: list[str] = []
        self.bore_pts: list[tuple[float, float]] = []

    def _face(self, i: int) -> OpticalFace:
        s = self.p.surfaces[i]
        return OpticalFace.of(i, float(self.p.vertex_z[i]), s)

    def lens_groups(self) -> None:
        """Every lens element, group by group (cemented elements share their group's rim): its outline, the
        group's rim and bore, and where the group's outer seats touch it. Reads [lens_edge] (allowance,
        semi_diameter_mm, chamfer, flat_faces, stepped_min_edge_mm, contact_margin_mm, finish), [barrel]
        radial_clearance_mm, [seats] clearance_mm and element (checked here), [checks] min_thickness_mm."""
        p, edge, clear, groups = self.p, self.spec.lens_edge, self.clear, self.groups
        if not groups:
            raise GeometryError("the prescription has no glass: no lens element to mount", field="surfaces")
        flat_faces = {n - 1 for n in edge.flat_faces}
        outer = {i for g in groups for i in (g[0], g[-1])}
        for n in edge.flat_faces:
            if n - 1 not in outer:
                raise GeometryError(f"surface {n} is not the outer face of a lens group, so it cannot be ground flat",
                                    field="lens_edge.flat_faces",
                                    valid="surface numbers of outer lens faces: " + ", ".join(str(i + 1) for i in sorted(outer)))
        n_el = 0
        for g in groups:
            R = group_rim(p, g, n_el + 1, edge)
            self.radii.append(R)
            self.bores.append(R + self.c_bore)
            built, stepped = lens_group([self._face(i) for i in g], R, self.chamfer, [clear[i] for i in g], self.min_t,
                                        edge.stepped_min_edge_mm, (g[0] in flat_faces, g[-1] in flat_faces))
            self.seats_of_groups.append(seat_of_group(built, stepped, g, clear, max(self.cm, self.c_glass)))
            elements = []
            for k in range(len(g) - 1):
                n_el += 1
                elements.append(self._element(n_el, built[k], g, k, R, k in stepped, flat_faces))
            self.lens_parts.append(elements)
        for R, g, sides in zip(self.radii, groups, self.seats_of_groups):
            for i, h, _ in sides:
                if h > R - self.chamfer - 1e-6:
                    raise GeometryError(
                        f"surface {i + 1}: contact height {h:.3f} mm (clear {clear[i]:.3f} mm + margin {self.cm}"
                        + (", outside a stepped element" if i not in (g[0], g[-1]) else "")
                        + f") lies beyond the edge chamfer at {R - self.chamfer:.3f} mm",
                        field="lens_edge.contact_margin_mm", valid="a smaller contact margin or chamfer, "
                        "or a larger edge allowance")
        seat_numbers = {int(grp[0].name.split("-")[1]) for grp in self.lens_parts[1:]}
        for number in self.spec.seats.element:
            if number not in seat_numbers:
                raise GeometryError(
                    f"element {number} has no seat of its own to choose (it is the first element, "
                    "cemented to the one before, or does not exist)", field=f"seats.element.{number}",
                    valid="the number of the first element of a lens group after the first: "
                          + ", ".join(str(n) for n in sorted(seat_numbers)))

    def _element(self, n_el: int, el: LensElement, g: tuple[int, ...], k: int, R: float, stepped: bool,
                 flat_faces: set[int]) -> PartPlan:
        """Element number n_el, the k-th of group g (rim R), as built: refused when a face ends inside its
        rim or it is too thin, with a note when it is stepped inside the group's rim or bevelled flat."""
        edge, clear, min_t = self.spec.lens_edge, self.clear, self.min_t
        a, b = g[k], g[k + 1]
        name = f"lens-{n_el}"
        short = face_beyond_reach(el)
        if short is not None:
            reach = short.profile.max_radius()
            outer_face = short.index in (g[0], g[-1])
            raise GeometryError(
                f"{name} reaches {el.outer_radius:.3f} mm from the axis, beyond the edge of surface "
                f"{short.index + 1} (radius {1.0 / short.curvature:g} mm, conic {short.conic:g}), whose "
                f"profile ends at {reach:.3f} mm", field=f"lens_edge.semi_diameter_mm.{n_el}",
                valid=f"a semi-diameter of at most {reach:.3f} mm"
                      + (f", or the face ground flat from its clear semi-diameter (lens_edge.flat_faces = "
                         f"[{short.index + 1}])" if outer_face else ""))
        if stepped:
            partner = f"lens-{n_el + (1 if k == 0 else -1)}"
            self.notes.append(f"{name}: stepped, edged to {el.outer_radius:.3f} mm (clear "
                              f"{max(clear[a], clear[b]):.3f} mm plus a "
                              f"{max(el.front_chamfer, el.back_chamfer):.3f} mm bevel; edge "
                              f"{el.edge_thickness():.3f} mm, lens_edge.stepped_min_edge_mm "
                              f"{edge.stepped_min_edge_mm}): at the group's {R:.3f} mm it would be "
                              f"{LensElement(self._face(a), self._face(b), R).edge_thickness():.3f} mm; the group is "
                              f"seated on {partner}'s cemented face outside it")
            return PartPlan(name, "lens", self.spec.finish_of(name, edge.finish), el)
        flats = [f"{side} face flat from {r:.3f} mm" for side, r in
                 (("front", el.front_flat_from), ("rear", el.back_flat_from)) if r is not None]
        if flats and {a, b} & flat_faces:
            self.notes.append(f"{name}: flat bevel ({', '.join(flats)}; lens_edge.flat_faces)")
        elif flats:
            ends = [fc for fc in (el.front, el.back) if not ends_inside(fc, R)]
            self.notes.append(f"{name}: flat bevel ({', '.join(flats)}): " + (
                f"surface {ends[0].index + 1}'s sphere ends at {ends[0].profile.max_radius():.3f} mm, inside "
                f"the {R:.3f} mm rim" if ends else "its faces close in toward the rim, the flat keeps the edge "
                f"{el.edge_thickness():.3f} mm thick at {R:.3f} mm"))
        if (el.center_thickness() < min_t or el.edge_thickness() < min_t) and not thin_plate([el.front, el.back], min_t):
            # rims from the smallest a seat outside the light allows to 2 mm beyond: a thin meniscus
            # is too thin at all of them, which no allowance can mend
            r_min = max(clear[a], clear[b]) + self.cm + el.front_chamfer + el.back_chamfer
            rims = np.linspace(r_min, max(R, r_min) + 2.0, 41)
            edges = [LensElement(self._face(a), self._face(b), r, el.front_chamfer, el.back_chamfer).edge_thickness()
                     for r in rims]
            j = int(np.argmax(edges))
            hopeless = el.center_thickness() >= min_t and edges[j] < min_t
            raise GeometryError(
                f"{name} is too thin: centre {el.center_thickness():.3f} mm, edge "
                f"{el.edge_thickness():.3f} mm at radius {R:.3f} mm (minimum {min_t} mm)"
                + (f"; no rim from {r_min:.3f} mm (clear semi-diameter, contact margin and chamfers) to "
                   f"{rims[-1]:.3f} mm is thicker than {edges[j]:.3f} mm (at {rims[j]:.3f} mm), so no seat "
                   "outside the light finds the minimum" if hopeless else ""),
                field="lens_edge.allowance_mm",
                valid=("a thicker element in the lens file" + (
                    f", or [checks] min_thickness_mm <= {edges[j]:.3f} with lens_edge.semi_diameter_mm.{n_el} = "
                    f"{rims[j]:.3f}" if edges[j] > 0 else "")) if hopeless
                else "a smaller edge allowance or chamfer, or a thicker element")
        return PartPlan(name, "lens", self.spec.finish_of(name, edge.finish), el)

    def _seated(self, gi: int, side: int) -> PartPlan:
        """The element the seat on side 0 (front) or 1 (rear) of group gi touches, with the outline it
        follows (a stepped group's GroupOutline)."""
        i, _, outline = self.seats_of_groups[gi][side]
        g = self.groups[gi]
        el = next(pp for pp, (a, b) in zip(self.lens_parts[gi], zip(g[:-1], g[1:])) if i == (a if side == 0 else b))
        return el if outline is el.template else PartPlan(el.name, el.kind, el.finish, outline)

    def _seat_at(self, gi: int, side: int) -> tuple[int, float]:
        """(surface index, contact height) where the seat on that side of group gi touches."""
        return self.seats_of_groups[gi][side][:2]

    def beam(self) -> None:
        """The beam envelope over the whole assembly, from the hood's mouth ([hood]) to the image plane."""
        hood = self.spec.hood
        z_lo = -(hood.length_mm + 50.0 if hood.enabled else 50.0)
        self.env = Envelope(self.p, z_lo, self.p.image_z)

    def _add_spacers(self, ends, od: float, ia: int, ib: int) -> None:
        """Spacers of outside radius od from (front_r, front_z, front_slope, back_r, back_z, back_slope,
        front part, back part), touching surface ia of the front part and ib of the back one (lenses)."""
        spec, min_t = self.spec, self.min_t
        for fr, fz, fm, br, bz, bm, pa, pb in ends:
            tube = None
            if bz - fz >= spec.vanes.long_gap_mm:
                t = max(od - spec.spacers.tube_wall_mm, fr, br)
                tube = t if t > max(fr, br) + 1e-6 else None
            sp = Spacer(fr, fz, fm, br, bz, bm, od, tube, spec.spacers.lip_mm)
            name = f"spacer-{len(self.spacers) + 1}"
            if sp.min_length() < min_t:
                keys = [k for part in (pa, pb) for k in _size_keys(part)]
                keys = list(dict.fromkeys(keys))  # in order, once each
                raise GeometryError(
                    f"{name} between {pa} and {pb} would be {sp.min_length():.3f} mm long (minimum {min_t} mm): "
                    f"{pa} and {pb} leave no room in the air gap between them (their sizes: "
                    f"{', '.join(keys)})", field=keys[0],
                    valid=f"a smaller {' or '.join(keys)}, a shoulder seat, or a larger air gap in the lens")
            if od - max(fr, br) < min_t:
                raise GeometryError(
                    f"{name} between {pa} and {pb}: radial wall {od - max(fr, br):.3f} mm (minimum {min_t} mm)",
                    field="lens_edge.allowance_mm", valid="a larger edge allowance")
            self.spacers.append(PartPlan(name, "spacer", spec.finish_of(name, spec.spacers.finish), sp))
            if pa.startswith("lens"):
                self.contacts.append(Contact(name, pa, ia, fr, self.clear[ia]))
            if pb.startswith("lens"):
                self.contacts.append(Contact(name, pb, ib, br, self.clear[ib]))

    def _retainer(self, el: PartPlan, h: float, side: int, R: float, r_out: float) -> tuple[str, Retainer]:
        """A retainer ring ([retainer]) on the front (side -1) or rear (+1) face of el (rim R) at contact
        height h, r_out outside, its bore opened where the beam grows; its name and template."""
        glass = el.template.front_z if side < 0 else el.template.back_z
        m = contact_slope(glass, h, min(R, r_out), side, self.tangent, self.wedge)
        ret = Retainer(h, float(glass(h)), m, side, r_out, self.spec.retainer.thickness_mm)
        ret.far_r = ring_opening(self.env, h, ret.far_face_z(), ret.contact_z, self.spec)
        name = f"retainer-{len(self.retainers) + 1}"
        check_ring_wall(name, ret.far_r, r_out, self.min_t)
        self.retainers.append(PartPlan(name, "retainer", self.spec.finish_of(name, self.spec.retainer.finish), ret))
        return name, ret

    def _bonded(self, el: PartPlan, side: int, R: float, surface: int) -> float:
        """The barrel's end beside el (rim R), bonded by its edge ([seats] front/rear = "bonded"): flush with
        the glass's farthest point on that side, so the bore covers the whole edge; nothing touches the face,
        so its clear aperture (surface `surface`) may reach the rim, as a catalogue lens's file often has it."""
        rs = np.linspace(0.0, R, 129)
        z = el.template.front_z(rs).min() if side < 0 else el.template.back_z(rs).max()
        which = "front" if side < 0 else "rear"
        self.notes.append(f"{el.name}: bonded into the barrel by its ground edge (seats.{which} = 'bonded'), no ring "
                          f"or shoulder on its {which} face (surface {surface + 1}), whose clear semi-diameter "
                          f"{self.clear[surface]:.3f} mm leaves {R - self.clear[surface]:.3f} mm of its {R:.3f} mm rim")
        return float(z)

    def _outer_diaphragm(self, od: float, face=None) -> Diaphragm:
        """A diaphragm on a stop in front of the first element or behind the last one (or on its face)."""
        dia = stop_diaphragm(self.spec, self.p, self.stop, od, float(self.p.vertex_z[self.stop]), face)
        self.parts.append(PartPlan("diaphragm", "diaphragm",
                                   self.spec.finish_of("diaphragm", self.spec.diaphragm.finish), dia))
        return dia

    def _lip_radius(self, dia: Diaphragm, z0: float, z1: float, side: str) -> float:
        """Bore of the barrel lip (z0..z1) that clamps an outer diaphragm: clear of the beam."""
        r = max(dia.face_inner_radius(side), self.env.max_over(z0, z1) + self.spec.spacers.aperture_margin_mm)
        if dia.outer_radius - r < self.min_t:
            raise GeometryError(f"the barrel lip holding the diaphragm would be {dia.outer_radius - r:.3f} mm "
                                f"high (minimum {self.min_t} mm)", field="spacers.aperture_margin_mm",
                                valid="a smaller aperture margin or a larger edge allowance")
        return r

    def front_seat(self) -> float:
        """What holds the first group from the object side; returns the barrel's front end z. A stop in
        front of (or on) lens 1: barrel lip | diaphragm | spacer | lens 1, no spacer on lens 1's face
        ([diaphragm], [barrel] lip_mm, [spacers]); else [seats] front: a retainer ring ([retainer]) or
        a barrel shoulder ([barrel] lip_mm)."""
        spec, env, stop, c_sp = self.spec, self.env, self.stop, self.c_sp
        first = self._seated(0, 0)
        el0, R0, bore0 = first.template, self.radii[0], self.bores[0]
        i0 = self.groups[0][0]
        s0, h0 = self._seat_at(0, 0)
        if stop <= i0:
            od = bore0 - c_sp
            dia = self._outer_diaphragm(od, (-1, el0.front_z, R0) if stop == i0 else None)
            fz = lambda r: float(dia.face_z("front", r))  # noqa: E731  (a cone on lens 1's face)
            dz0 = min(fz(dia.inner_radius), fz(od))
            z_front = dz0 - spec.barrel.lip_mm
            r_lip = self._lip_radius(dia, z_front, max(fz(dia.inner_radius), fz(od)), "front")
            self.bore_pts += [(r_lip, z_front), (r_lip, fz(r_lip)), (bore0, fz(bore0))]
            if stop < i0:
                dz1 = dia.z_range()[1]
                m = contact_slope(el0.front_z, h0, min(R0, od), -1, self.tangent, self.wedge)
                hd1 = max(dia.face_inner_radius("rear"), env.max_over(dz1, dz1 + 1.0) + spec.spacers.aperture_margin_mm)
                self._add_spacers([(hd1, dz1, EPS_SLOPE, h0, float(el0.front_z(h0)), m, "diaphragm", first.name)],
                                  od, -1, s0)
        elif spec.seats.front == "bonded":
            z_front = self._bonded(first, -1, R0, s0)
            self.bore_pts.append((bore0, z_front))
        elif spec.seats.front == "retainer":
            name, ret = self._retainer(first, h0, -1, R0, bore0 - c_sp)
            self.contacts.append(Contact(name, first.name, s0, h0, self.clear[s0]))
            z_front = ret.far_face_z()
            self.bore_pts.append((bore0, z_front))
        else:
            m = contact_slope(el0.front_z, h0, R0, -1, self.tangent, self.wedge)
            cz = lambda r: float(el0.front_z(h0)) - m * (r - h0)  # noqa: E731
            z_front = cz(bore0) - spec.barrel.lip_mm
            self.bore_pts += [(ring_opening(env, h0, z_front, cz(h0), spec), z_front), (h0, cz(h0)), (bore0, cz(bore0))]
            self.contacts.append(Contact("barrel", first.name, s0, h0, self.clear[s0]))
        return z_front

    def gaps(self) -> None:
        """What holds the groups apart in each air gap, by [seats] element (else [seats] default): a
        spacer, a barrel shoulder, a shoulder behind and a retainer in front, or one lens resting on the
        other (glass); always spacers, with the diaphragm between them, in the gap that holds the stop."""
        stop, groups, seats = self.stop, self.groups, self.spec.seats
        stop_placed = stop <= groups[0][0] or stop >= groups[-1][-1]
        for gi in range(len(groups) - 1):
            (sa, hA), (sb, hB) = self._seat_at(gi, 1), self._seat_at(gi + 1, 0)
            gap = _Gap(self._seated(gi, 1), self._seated(gi + 1, 0), groups[gi][-1], groups[gi + 1][0],
                       sa, hA, sb, hB, self.radii[gi], self.radii[gi + 1], self.bores[gi], self.bores[gi + 1],
                       int(self.lens_parts[gi + 1][0].name.split("-")[1]))
            stop_here = gap.ia <= stop <= gap.ib
            seat = "spacer" if stop_here else seats.element.get(gap.element_no, seats.default)
            if seat == "retainer":
                self._retainer_gap(gap)
            elif seat == "glass":
                self._glass_gap(gap)
            elif seat == "shoulder":
                self._shoulder_gap(gap)
            else:
                self._spacer_gap(gap, stop_here)
                stop_placed = stop_placed or stop_here
        if not stop_placed:
            raise GeometryError(
                f"the stop (surface {stop + 1}) lies inside a cemented group, where no diaphragm fits; "
                "the mount layout needs it in an air gap or on a group's outer face", field=f"surface[{stop + 1}]",
                valid="a stop in an air gap (between two lens groups, in front of the first or behind the last) "
                      "or on the outer face of a lens group")

    def _retainer_gap(self, g: _Gap) -> None:
        """A barrel shoulder behind A ([barrel] lip_mm thick) and a retainer ring in front of B."""
        A, B, hA, min_t = g.A, g.B, g.hA, self.min_t
        mA = contact_slope(A.template.back_z, hA, g.RA, +1, self.tangent, self.wedge)
        cA = lambda r, z0=float(A.template.back_z(hA)), m=mA, h=hA: z0 + m * (r - h)  # noqa: E731
        name, ret = self._retainer(B, g.hB, -1, g.RB, g.bore_b - self.c_sp)
        # the shoulder's rear face: a lip's thickness behind A, clear of the ring's far face
        z_sh = max(cA(g.bore_a), cA(hA)) + self.spec.barrel.lip_mm
        room = ret.far_face_z() - self.c_glass - z_sh
        if room < 0:
            raise GeometryError(
                f"no room for a shoulder behind {A.name} and a retainer in front of {B.name}: "
                f"{-room:.3f} mm short", field=f"seats.element.{g.element_no}",
                valid="'spacer' or 'shoulder', a thinner retainer or barrel lip, or a larger air gap")
        r_sh = ring_opening(self.env, hA, z_sh, cA(hA), self.spec)
        if g.bore_b - r_sh < min_t:
            raise GeometryError(f"the shoulder behind {A.name} would be {g.bore_b - r_sh:.3f} mm high "
                                f"(minimum {min_t} mm)", field=f"seats.element.{g.element_no}",
                                valid="'spacer', or a larger edge allowance")
        self.bore_pts += [(g.bore_a, cA(g.bore_a)), (hA, cA(hA)), (r_sh, z_sh), (g.bore_b, z_sh)]
        self.contacts += [Contact("barrel", A.name, g.sa, hA, self.clear[g.sa]),
                          Contact(name, B.name, g.sb, g.hB, self.clear[g.sb])]

    def _glass_gap(self, g: _Gap) -> None:
        """The element with the smaller rim rests its rim corner on the other's face; the bore steps between."""
        A, B, env, c_glass = g.A, g.B, self.env, self.c_glass
        self.bore_pts += glass_seat_bore(A, B, g.RA, g.RB, g.bore_a, g.bore_b, c_glass, g.element_no)
        # the rim corner that rests on the other face; that face is touched where no light
        # reaches it (the envelope there), which may lie inside the file's semi-diameter
        small, big, i_big = (A, B, g.ib) if g.RA < g.RB else (B, A, g.ia)
        rim = small.template.outer_radius - (small.template.back_chamfer if small is A
                                             else small.template.front_chamfer)
        z_rim = float((small.template.back_z if small is A else small.template.front_z)(rim))
        gap = (float(B.template.front_z(rim)) - z_rim) if small is A else (z_rim - float(A.template.back_z(rim)))
        if gap > c_glass:
            raise GeometryError(
                f"{small.name} would rest on {big.name} but its rim corner at r = {rim:.3f} mm stays "
                f"{gap:.3f} mm off that face", field=f"lens_edge.semi_diameter_mm.{small.name.split('-')[1]}",
                valid=f"the radius where the faces meet plus the chamfer, or seat 'spacer' or 'shoulder'")
        light = float(env.exact([z_rim])[0])
        self.contacts.append(Contact(small.name, big.name, i_big, rim, min(light, self.clear[i_big])))
        if rim < light + BEAM_CLEAR_MM:
            raise GeometryError(
                f"{small.name} would rest on {big.name} at r = {rim:.3f} mm, inside the beam there "
                f"({light:.3f} mm)", field=f"seats.element.{g.element_no}", valid="'spacer' or 'shoulder'")

    def _shoulder_gap(self, g: _Gap) -> None:
        """A barrel shoulder between A and B, touching both ([checks] min_thickness_mm thick at least)."""
        A, B, hA, hB = g.A, g.B, g.hA, g.hB
        mA = contact_slope(A.template.back_z, hA, g.RA, +1, self.tangent, self.wedge)
        mB = contact_slope(B.template.front_z, hB, g.RB, -1, self.tangent, self.wedge)
        cA = lambda r, z0=float(A.template.back_z(hA)), m=mA, h=hA: z0 + m * (r - h)  # noqa: E731
        cB = lambda r, z0=float(B.template.front_z(hB)), m=mB, h=hB: z0 - m * (r - h)  # noqa: E731
        rr = np.linspace(max(hA, hB), min(g.bore_a, g.bore_b), 50)
        thick = float(np.min([cB(r) - cA(r) for r in rr]))
        if thick < self.min_t:
            raise GeometryError(
                f"the barrel shoulder between {A.name} and {B.name} is {thick:.3f} mm thick "
                f"(minimum {self.min_t} mm)", field=f"seats.element.{g.element_no}",
                valid="'spacer', or a larger air gap")
        self.bore_pts += [(g.bore_a, cA(g.bore_a)), (hA, cA(hA)), (hB, cB(hB)), (g.bore_b, cB(g.bore_b))]
        self.contacts += [Contact("barrel", A.name, g.sa, hA, self.clear[g.sa]),
                          Contact("barrel", B.name, g.sb, hB, self.clear[g.sb])]

    def _spacer_gap(self, g: _Gap, stop_here: bool) -> None:
        """A spacer from A to B ([spacers]), or where the stop lies, the diaphragm ([diaphragm]) with a
        spacer on each side that has room for one; the bore steps where the glass outside them ends."""
        A, B, ia, ib, hA, hB, RA, RB = g.A, g.B, g.ia, g.ib, g.hA, g.hB, g.RA, g.RB
        spec, stop, c_glass = self.spec, self.stop, self.c_glass
        od = min(g.bore_a, g.bore_b) - self.c_sp
        mA = contact_slope(A.template.back_z, hA, min(RA, od), +1, self.tangent, self.wedge)
        mB = contact_slope(B.template.front_z, hB, min(RB, od), -1, self.tangent, self.wedge)
        ends = []  # (front_r, front_z, front_slope, back_r, back_z, back_slope, front part, back part)
        if stop_here:
            faces = {ia: (+1, A.template.back_z, RA), ib: (-1, B.template.front_z, RB)}
            # a stop on A's rear or B's front face: the plate follows that face; a stop plane with
            # no room for a spacer between it and A (B): the plate follows A's (B's) face up to it
            hug = stop if stop in faces else None
            while True:
                dia = stop_diaphragm(spec, self.p, stop, od, float(self.p.vertex_z[stop]), faces.get(hug))
                ends = diaphragm_spacer_ends(dia, self.env, spec, od, hug, ia, ib, (hA, mA, A), (hB, mB, B))
                short = [ia if e[7] == "diaphragm" else ib for e in ends
                         if Spacer(*e[:6], od).min_length() < self.min_t]
                if hug is not None or not short:
                    break
                hug = short[0]
            self.parts.append(PartPlan("diaphragm", "diaphragm", spec.finish_of("diaphragm", spec.diaphragm.finish),
                                       dia))
        else:
            ends.append((hA, float(A.template.back_z(hA)), mA, hB, float(B.template.front_z(hB)), mB, A.name, B.name))
        self._add_spacers(ends, od, g.sa, g.sb)
        r_in = od + self.c_sp
        # clear of the glass by c_glass: the step does not hold the lens, and a step face
        # through the glass's corner would leave a sub-micrometre sliver beside it
        za = float(A.template.back_z(radii_to_rim(min(r_in, RA), RA, A.template.back_chamfer)).max()) + c_glass
        zb = float(B.template.front_z(radii_to_rim(min(r_in, RB), RB, B.template.front_chamfer)).min()) - c_glass
        if zb < za:
            raise GeometryError(f"the barrel cannot step between {A.name} and {B.name}: their edges overlap "
                                f"axially by {za - zb:.3f} mm", field="lens_edge.allowance_mm",
                                valid="a smaller edge allowance")
        self.bore_pts += [(g.bore_a, za), (r_in, za), (r_in, zb), (g.bore_b, zb)]

    def rear_seat(self) -> float:
        """What holds the last group from the image side; returns the barrel's rear end z. A stop behind
        (or on) the last lens L: lens L | spacer | diaphragm | barrel lip, no spacer on lens L's face
        ([diaphragm], [barrel] lip_mm, [spacers]); else [seats] rear: a barrel shoulder ([barrel] lip_mm)
        or a retainer ring ([retainer])."""
        spec, env, stop, c_sp = self.spec, self.env, self.stop, self.c_sp
        gl = len(self.groups) - 1
        last = self._seated(gl, 1)
        elL, RL, boreL = last.template, self.radii[gl], self.bores[gl]
        iL = self.groups[gl][-1]
        sL, hL = self._seat_at(gl, 1)
        if stop >= iL:
            od = boreL - c_sp
            dia = self._outer_diaphragm(od, (+1, elL.back_z, RL) if stop == iL else None)
            rz = lambda r: float(dia.face_z("rear", r))  # noqa: E731  (a cone on lens L's face)
            dz1 = max(rz(dia.inner_radius), rz(od))
            z_back = dz1 + spec.barrel.lip_mm
            r_lip = self._lip_radius(dia, min(rz(dia.inner_radius), rz(od)), z_back, "rear")
            if stop > iL:
                dz0 = dia.z_range()[0]
                m = contact_slope(elL.back_z, hL, min(RL, od), +1, self.tangent, self.wedge)
                hd0 = max(dia.face_inner_radius("front"),
                          env.max_over(dz0 - 1.0, dz0) + spec.spacers.aperture_margin_mm)
                self._add_spacers([(hL, float(elL.back_z(hL)), m, hd0, dz0, EPS_SLOPE, last.name, "diaphragm")],
                                  od, sL, -1)
            self.bore_pts += [(boreL, rz(boreL)), (r_lip, rz(r_lip)), (r_lip, z_back)]
        elif spec.seats.rear == "bonded":
            z_back = self._bonded(last, +1, RL, sL)
            self.bore_pts.append((boreL, z_back))
        elif spec.seats.rear == "shoulder":
            m = contact_slope(elL.back_z, hL, RL, +1, self.tangent, self.wedge)
            cz = lambda r: float(elL.back_z(hL)) + m * (r - hL)  # noqa: E731
            z_back = cz(boreL) + spec.barrel.lip_mm
            self.bore_pts += [(boreL, cz(boreL)), (hL, cz(hL)), (ring_opening(env, hL, z_back, cz(hL), spec), z_back)]
            self.contacts.append(Contact("barrel", last.name, sL, hL, self.clear[sL]))
        else:
            name, ret = self._retainer(last, hL, +1, RL, boreL - c_sp)
            self.contacts.append(Contact(name, last.name, sL, hL, self.clear[sL]))
            z_back = ret.far_face_z()
            self.bore_pts.append((boreL, z_back))
        return z_back

    def barrel(self) -> float:
        """The barrel around the bore the seats stepped, [barrel] wall_mm thick; its outside radius."""
        r_barrel = max(r for r, _ in self.bore_pts) + self.spec.barrel.wall_mm
        barrel = Barrel(tuple((float(r), float(z)) for r, z in self.bore_pts), float(r_barrel))
        finish = self.spec.finish_of("barrel", self.spec.barrel.finish)
        self.parts.insert(0, PartPlan("barrel", "barrel", finish, barrel))
        return r_barrel

    def part_kinds(self, z_front: float, z_back: float, r_barrel: float) -> Layout:
        """Around the seated stack, every registered part kind's parts (`cad.stages`: the built-in hood with
        its vanes and detector housing, `cad.kinds`, then any plug-in's), and the layout of every part in order."""
        spec, p = self.spec, self.p
        i0 = self.groups[0][0]
        rho = np.linspace(0.0, self.clear[i0], APERTURE_SAMPLES)
        aperture = (rho, self._seated(0, 0).template.front_z(rho))  # the first surface over its clear aperture
        parts = self.parts
        ordered = [parts[0]] + [pp for grp in self.lens_parts for pp in grp] + self.retainers + self.spacers + parts[1:]
        mount = Mount(p, spec, self.env, tuple(ordered), self.notes, z_front, z_back, r_barrel, self.bore_pts[0][0],
                      self.bore_pts[-1][0], aperture)
        return Layout(p, ordered + place_kinds(mount), self.contacts, self.env, self.notes)


__all__ = ["plan"]
