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
  whose slope keeps it off the glass everywhere else (`contact_slope`).
* The bore steps where the glass outside the spacer's radius ends, so no part
  overlaps another; `checks` verifies it on the final profiles.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from lensmount.cad.lens_groups import lens_group, seat_of_group
from lensmount.design.mount import MountSpec
from lensmount.errors import GeometryError
from lensmount.optics.prescription import Prescription
from lensmount.templates.barrel import Barrel
from lensmount.templates.diaphragm import Diaphragm
from lensmount.templates.lens_element import LensElement, OpticalFace
from lensmount.templates.retainer import Retainer
from lensmount.templates.spacer import Spacer

_SLOPE_SAMPLES = 256
_EPS_SLOPE = 1e-6  # keeps a contact a line, not a face, against rounding
ENVELOPE_STEP_MM = 0.25
APERTURE_SAMPLES = 65  # points from the axis to the rim of the entrance aperture (vane sight lines)


@dataclass
class PartPlan:
    """One part: name, kind, finish and the template that builds it."""

    name: str
    kind: str
    finish: str
    template: object


@dataclass
class Contact:
    """A mechanical contact on an optical surface (for the clear-aperture check)."""

    part: str
    lens: str
    surface: int
    height: float
    clear: float


@dataclass
class Layout:
    prescription: Prescription  # with clear semi-diameters
    parts: list[PartPlan]
    contacts: list[Contact]
    envelope: "Envelope"
    notes: list[str] = field(default_factory=list)
    beam: object = None  # a folded path's rays (cad.catadioptric.BeamPaths): the beam check runs on them

    def part(self, name: str) -> PartPlan:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(name)


class Envelope:
    """Beam envelope radius at any z, interpolated from a fine grid of real-ray envelopes.

    In an air gap each ray's radius is a convex function of z, so the envelope is
    convex there and the chord between two grid values bounds it from above; across
    a surface it is only an approximation, which is why `exact` exists for checks.
    """

    def __init__(self, prescription: Prescription, z_min: float, z_max: float, step: float = ENVELOPE_STEP_MM):
        n = max(2, int(np.ceil((z_max - z_min) / step)) + 1)
        self.prescription = prescription
        self.z = np.linspace(z_min, z_max, n)
        self.r = _envelope_grid(prescription, float(z_min), float(z_max), n)

    def exact(self, z) -> np.ndarray:
        """The real-ray envelope at each z (slow: traces the beam), (n,)."""
        return _exact_envelope(self.prescription, z)

    def at(self, z) -> np.ndarray:
        """Envelope at each z by linear interpolation: (n,)."""
        return np.interp(np.asarray(z, dtype=np.float64), self.z, self.r)

    def max_over(self, z0: float, z1: float) -> float:
        """Largest envelope radius for z in [z0, z1], mm."""
        a, b = min(z0, z1), max(z0, z1)
        inside = self.r[(self.z > a) & (self.z < b)]
        ends = self.at([a, b])
        return float(max(ends.max(), inside.max() if len(inside) else 0.0))


@lru_cache(maxsize=8)
def _envelope_grid(prescription: Prescription, z_min: float, z_max: float, n: int) -> np.ndarray:
    """Envelope radii on a grid, kept per lens and grid (read-only): `init` checks the starter mount
    with the same layout that `regenerate` then plans, and a design loop replans one lens often."""
    r = _exact_envelope(prescription, np.linspace(z_min, z_max, n))
    r.flags.writeable = False
    return r


def _exact_envelope(prescription: Prescription, z) -> np.ndarray:
    from lensmount.optics.apertures import beam_envelope

    z = np.atleast_1d(np.asarray(z, dtype=np.float64))
    if not len(z):
        return np.zeros(0)
    return np.nan_to_num(beam_envelope(prescription, z), nan=0.0, posinf=0.0, neginf=0.0)


def contact_slope(boundary, h: float, r_max: float, side: int, tangent: bool, wedge: float) -> float:
    """Cone slope m of an end face touching the glass at radius h.

    boundary(r) is the glass's z at r (the face toward the part); side = +1 when the
    part lies behind the glass (larger z), -1 in front. The face z_c + side·m·(r − h)
    must stay off the glass for h < r <= r_max: m >= side·(z(r) − z(h)) / (r − h).
    Sharp-corner contact: the face leaves the glass at least at the angle atan(wedge),
    m >= that bound + wedge, so the gap grows by at least wedge·(r − h) and never runs
    alongside the glass at sub-micrometre distance (on a surface concave toward the
    part the bare bound would hug it); never steeper into the part than flat (m >= 0).
    Tangent contact: the surface's own slope at h, m = side·z'(h), safe on a surface
    convex toward the part (m may then be negative; the gap grows quadratically, as
    a tangent contact does); on a concave one the sharp rule wins.
    """
    zh = float(boundary(h))
    need = -np.inf
    if r_max > h + 1e-9:
        rs = np.linspace(h, r_max, _SLOPE_SAMPLES)[1:]
        need = float((side * (boundary(rs) - zh) / (rs - h)).max())
    sharp = max(0.0, need + wedge)
    if tangent:
        dh = 1e-4
        along = side * float(boundary(h + dh) - boundary(h - dh)) / (2 * dh)
        return (along if along >= need else sharp) + _EPS_SLOPE
    return sharp + _EPS_SLOPE


def _opening(env: "Envelope", h: float, z_far: float, z_contact: float, spec: MountSpec) -> float:
    """Bore radius at a ring's far face: the contact radius, or wider where the beam grows.

    The bore runs straight from (h, z_contact) to (r, z_far); the beam is convex in z
    in air, so clearing both ends (with the spacer margin) clears the whole bore.
    """
    beam = env.max_over(min(z_far, z_contact), max(z_far, z_contact))
    return float(max(h, beam + spec.spacers.aperture_margin_mm if beam > h else h))


def _check_ring(name: str, bore: float, outside: float, min_t: float) -> None:
    if outside - bore < min_t:
        raise GeometryError(
            f"{name}: its bore must open to {bore:.3f} mm to clear the beam, leaving a wall of "
            f"{outside - bore:.3f} mm inside its outside radius {outside:.3f} mm (minimum {min_t} mm)",
            field="retainer.thickness_mm", valid="a thinner ring, a smaller aperture margin or a larger lens")


def _radii(lo: float, R: float, chamfer: float) -> np.ndarray:
    """Radii from lo to R including the chamfer's corner (where the glass's z peaks)."""
    rs = np.linspace(lo, R, 129)
    return np.unique(np.concatenate([rs, [R - chamfer] if R - chamfer >= lo else []]))


def pupil_edge_radius(prescription: Prescription, z0: float, z1: float) -> float:
    """Largest radius, for z in [z0, z1], of the on-axis ray entering at the designed EPD/2.

    A diaphragm whose bore is this radius over its land passes exactly the designed
    entrance pupil (primary wavelength), wherever the land sits: on a dummy stop plane,
    or next to a curved stop surface where the paraxial stop height no longer applies.
    """
    from lensmount.optics.apertures import beam_envelope
    from lensmount.optics.paraxial import paraxial
    from lensmount.optics.realrays import trace

    if prescription.object_telecentric:   # the object-space NA is the aperture: the stop passes every field's beam
        return float(beam_envelope(prescription, np.linspace(z0, z1, 9)).max())
    h = 0.5 * paraxial(prescription).epd
    rays = trace(prescription, np.array([[0.0, h, -1.0]]), np.array([[0.0, 0.0, 1.0]]), clip=False)
    pts = np.concatenate([rays.origins[None], rays.points], axis=0)[:, 0]  # (S+2, 3) polyline
    zs = np.linspace(z0, z1, 9)
    return float(np.interp(zs, pts[:, 2], np.abs(pts[:, 1])).max())


def _size_keys(part: str) -> list[str]:
    """The mount.toml keys that set how much of an air gap a part takes along the axis."""
    if part == "diaphragm":
        return ["diaphragm.thickness_mm"]
    if part.startswith("retainer"):
        return ["retainer.thickness_mm"]
    if part.startswith("vane"):
        return ["vanes.thickness_mm"]
    return ["lens_edge.contact_margin_mm"]  # a lens: where its seat touches


def _diaphragm(spec, p, stop, od, z_stop, face=None) -> Diaphragm:
    """The diaphragm for the stop at z_stop; its land passes the designed pupil.

    face None: the knife edge on the stop plane (a dummy stop surface in an air gap).
    face (side, glass, R): the plate follows the face glass(r) of the lens in front of it
    (side +1) or behind it (side -1), R that lens's radius: its land sits just off the
    glass where the face crosses the pupil's edge, the plate a cone that clears the glass
    outward of it (`contact_slope`), so the plate limits no field more than the face itself.
    That is the stop on a lens face, or a stop plane so close to a curved face that no
    spacer fits between them; there the land stays on the stop plane wherever the glass
    leaves room (the field beams cross the axis there), else as close to it as the glass allows.
    """
    ds = spec.diaphragm
    land = ds.land_mm
    args = (od, ds.thickness_mm, land, ds.bevel_angle_deg, ds.bevel_side)
    if face is None:
        return Diaphragm(z_stop, pupil_edge_radius(p, z_stop - 0.5 * land, z_stop + 0.5 * land), *args)
    side, glass, R = face
    gap = spec.seats.clearance_mm  # air between glass and plate at the land
    wedge = float(np.tan(np.radians(spec.seats.wedge_deg)))
    on_face = abs(float(glass(0.0)) - z_stop) < 1e-9
    r0 = float(p.surfaces[stop].clear_semi_diameter)
    for _ in range(4):  # the land's z depends on its radius through the glass's sag: settle both
        off0, off1 = Diaphragm(0.0, r0, *args).z_range()  # face offsets from the land centre
        near = off0 if side > 0 else off1                   # the face toward the glass
        zc = float(glass(r0)) + side * gap - near
        if on_face or side * (z_stop - zc) <= 0.0:
            m = side * contact_slope(glass, r0, min(od, R), side, False, wedge)
        else:  # the stop plane is farther from the glass: the land stays on it, the plate
            zc = z_stop  # only as steep as keeps it `gap` off the glass outward
            rs = np.linspace(r0, max(min(od, R), r0 + 1e-6), _SLOPE_SAMPLES)[1:]
            need = float((side * (glass(rs) + side * gap - (zc + near)) / (rs - r0)).max())
            m = side * (max(0.0, need) + _EPS_SLOPE)
        lo = zc - 0.5 * land
        r0 = pupil_edge_radius(p, lo, lo + land)
    return Diaphragm(zc, r0, *args, slope=m)


def _diaphragm_spacer_ends(dia, env, spec, od, hug, ia, ib, a, b) -> list[tuple]:
    """Spacers between lens A and the diaphragm and between the diaphragm and lens B, as
    `add_spacers` ends; none on the side whose face the plate follows (`hug`).
    a, b: (contact height, contact slope, lens PartPlan) of A's rear and B's front face."""
    (hA, mA, A), (hB, mB, B) = a, b
    margin = spec.spacers.aperture_margin_mm

    def bore(side: str, reach: float) -> float:
        """Inner corner of the spacer on the plate's front or rear face: above the beam over the
        millimetre next to where it meets the plate (on a cone that z moves with the corner)."""
        r = dia.face_inner_radius(side)
        for _ in range(20):
            z = float(dia.face_z(side, r))
            r_next = max(dia.face_inner_radius(side), env.max_over(z, z + reach) + margin)
            if r_next <= r + 1e-9:
                break
            r = r_next
        return r

    hd0, hd1 = bore("front", -1.0), bore("rear", 1.0)
    ends = []
    if hug != ia:
        ends.append((hA, float(A.template.back_z(hA)), mA, hd0, float(dia.face_z("front", hd0)),
                     _EPS_SLOPE - dia.slope, A.name, "diaphragm"))
    if hug != ib:
        ends.append((hd1, float(dia.face_z("rear", hd1)), dia.slope + _EPS_SLOPE, hB,
                     float(B.template.front_z(hB)), mB, "diaphragm", B.name))
    return ends


BEAM_CLEAR_MM = 0.01  # a glass seat's contact at least this far outside the light


def _glass_seat(A, B, RA, RB, bore_a, bore_b, c_glass, element_no) -> list[tuple[float, float]]:
    """Barrel bore points where lens A and lens B sit on each other (seat "glass"): the bore steps
    from the smaller element's to the larger's `c_glass` clear of the larger's glass outside the
    smaller's bore; the smaller element's edge cylinder must start before that step (the bore holds it)."""
    if RA < RB:   # A nests into B's front: step just in front of B's glass outside A's bore
        rs = _radii(min(bore_a, RB), RB, B.template.front_chamfer)
        z = float(B.template.front_z(rs).min()) - c_glass
        inside = z > A.template.edge_z()[0]
    else:         # B nests into A's rear
        rs = _radii(min(bore_b, RA), RA, A.template.back_chamfer)
        z = float(A.template.back_z(rs).max()) + c_glass
        inside = z < B.template.edge_z()[1]
    if not inside:
        raise GeometryError(f"{A.name} and {B.name} cannot sit on each other: the barrel step between their "
                            "bores would pass the smaller one's whole edge", field=f"seats.element.{element_no}",
                            valid="'spacer' or 'shoulder'")
    return [(bore_a, z), (bore_b, z)]


def plan(prescription: Prescription, spec: MountSpec) -> Layout:
    """Place every part. Raises GeometryError for a mount that cannot be built."""
    from lensmount.optics.apertures import with_clear_semi_diameters

    p = prescription
    if any(s.clear_semi_diameter is None for s in p.surfaces):
        p = with_clear_semi_diameters(p)
    if p.has_mirrors:
        from lensmount.cad.catadioptric import plan_catadioptric

        return plan_catadioptric(p, spec)
    surf, zv = p.surfaces, p.vertex_z
    clear = [float(s.clear_semi_diameter) for s in surf]
    edge = spec.lens_edge
    chamfer = edge.chamfer_mm if edge.style == "chamfered" else 0.0
    cm, tangent = edge.contact_margin_mm, spec.seats.contact == "tangent"
    wedge, c_glass = float(np.tan(np.radians(spec.seats.wedge_deg))), spec.seats.clearance_mm
    c_bore, c_sp = spec.barrel.radial_clearance_mm, spec.spacers.radial_clearance_mm
    min_t = spec.checks.min_thickness_mm
    parts: list[PartPlan] = []
    contacts: list[Contact] = []
    notes: list[str] = []

    def face(i):
        s = surf[i]
        return OpticalFace(i, float(zv[i]), s.curvature, s.conic, tuple(s.aspheric))

    # ---- lens elements, grouped -------------------------------------------------------
    groups = p.lens_groups()
    if not groups:
        raise GeometryError("the prescription has no glass: no lens element to mount", field="surfaces")
    flat_faces = {n - 1 for n in edge.flat_faces}
    outer = {i for g in groups for i in (g[0], g[-1])}
    for n in edge.flat_faces:
        if n - 1 not in outer:
            raise GeometryError(f"surface {n} is not the outer face of a lens group, so it cannot be ground flat",
                                field="lens_edge.flat_faces",
                                valid="surface numbers of outer lens faces: " + ", ".join(str(i + 1) for i in sorted(outer)))
    lens_parts: list[list[PartPlan]] = []
    seats_of_groups: list = []   # per group: (front, back) seats, seat_of_group
    radii, bores = [], []
    n_el = 0
    for g in groups:
        mech = [surf[i].mechanical_semi_diameter if surf[i].mechanical_semi_diameter is not None
                else clear[i] + edge.allowance_mm for i in g]
        overrides = [edge.semi_diameter_mm[n_el + k + 1] for k in range(len(g) - 1)
                     if n_el + k + 1 in edge.semi_diameter_mm]
        R = float(max(overrides)) if overrides else float(max(mech))
        radii.append(R)
        bores.append(R + c_bore)
        elements = []
        built, stepped = lens_group([face(i) for i in g], R, chamfer, [clear[i] for i in g], min_t,
                                    edge.stepped_min_edge_mm, (g[0] in flat_faces, g[-1] in flat_faces))
        seats_of_groups.append(seat_of_group(built, stepped, g, clear, max(cm, c_glass)))
        for k, (a, b) in enumerate(zip(g[:-1], g[1:])):
            n_el += 1
            el = built[k]
            name = f"lens-{n_el}"
            if k in stepped:
                partner = f"lens-{n_el + (1 if k == 0 else -1)}"
                notes.append(f"{name}: stepped, edged to {el.outer_radius:.3f} mm (clear {max(clear[a], clear[b]):.3f} "
                             f"mm plus a {max(el.front_chamfer, el.back_chamfer):.3f} mm bevel; edge "
                             f"{el.edge_thickness():.3f} mm, lens_edge.stepped_min_edge_mm "
                             f"{edge.stepped_min_edge_mm}): at the group's {R:.3f} mm it would be "
                             f"{LensElement(face(a), face(b), R).edge_thickness():.3f} mm; the group is seated on "
                             f"{partner}'s cemented face outside it")
                elements.append(PartPlan(name, "lens", spec.finish_of(name, edge.finish), el))
                continue
            flats = [f"{side} face flat from {r:.3f} mm" for side, r in
                     (("front", el.front_flat_from), ("rear", el.back_flat_from)) if r is not None]
            if flats and {a, b} & flat_faces:
                notes.append(f"{name}: flat bevel ({', '.join(flats)}; lens_edge.flat_faces)")
            elif flats:
                notes.append(f"{name}: flat bevel ({', '.join(flats)}): its faces close in toward the rim, "
                             f"the flat keeps the edge {el.edge_thickness():.3f} mm thick at {R:.3f} mm")
            if el.center_thickness() < min_t or el.edge_thickness() < min_t:
                # rims from the smallest a seat outside the light allows to 2 mm beyond: a thin meniscus
                # is too thin at all of them, which no allowance can mend
                r_min = max(clear[a], clear[b]) + cm + el.front_chamfer + el.back_chamfer
                rims = np.linspace(r_min, max(R, r_min) + 2.0, 41)
                edges = [LensElement(face(a), face(b), r, el.front_chamfer, el.back_chamfer).edge_thickness()
                         for r in rims]
                k = int(np.argmax(edges))
                hopeless = el.center_thickness() >= min_t and edges[k] < min_t
                raise GeometryError(
                    f"{name} is too thin: centre {el.center_thickness():.3f} mm, edge "
                    f"{el.edge_thickness():.3f} mm at radius {R:.3f} mm (minimum {min_t} mm)"
                    + (f"; no rim from {r_min:.3f} mm (clear semi-diameter, contact margin and chamfers) to "
                       f"{rims[-1]:.3f} mm is thicker than {edges[k]:.3f} mm (at {rims[k]:.3f} mm), so no seat "
                       "outside the light finds the minimum" if hopeless else ""),
                    field="lens_edge.allowance_mm",
                    valid=("a thicker element in the lens file" + (
                        f", or [checks] min_thickness_mm <= {edges[k]:.3f} with lens_edge.semi_diameter_mm.{n_el} = "
                        f"{rims[k]:.3f}" if edges[k] > 0 else "")) if hopeless
                    else "a smaller edge allowance or chamfer, or a thicker element")
            elements.append(PartPlan(name, "lens", spec.finish_of(name, edge.finish), el))
        lens_parts.append(elements)
    for R, g, sides in zip(radii, groups, seats_of_groups):
        for i, h, _ in sides:
            if h > R - chamfer - 1e-6:
                raise GeometryError(
                    f"surface {i + 1}: contact height {h:.3f} mm (clear {clear[i]:.3f} mm + margin {cm}"
                    + (", outside a stepped element" if i not in (g[0], g[-1]) else "")
                    + f") lies beyond the edge chamfer at {R - chamfer:.3f} mm",
                    field="lens_edge.contact_margin_mm", valid="a smaller contact margin or chamfer, "
                    "or a larger edge allowance")

    seat_numbers = {int(grp[0].name.split("-")[1]) for grp in lens_parts[1:]}
    for number in spec.seats.element:
        if number not in seat_numbers:
            raise GeometryError(
                f"element {number} has no seat of its own to choose (it is the first element, "
                "cemented to the one before, or does not exist)", field=f"seats.element.{number}",
                valid="the number of the first element of a lens group after the first: "
                      + ", ".join(str(n) for n in sorted(seat_numbers)))

    def seated(gi, side):
        """The element a seat touches, with the outline it follows (a stepped group's GroupOutline)."""
        i, _, outline = seats_of_groups[gi][side]
        el = next(pp for pp, (a, b) in zip(lens_parts[gi], zip(groups[gi][:-1], groups[gi][1:]))
                  if i == (a if side == 0 else b))
        return el if outline is el.template else PartPlan(el.name, el.kind, el.finish, outline)

    def first_el(gi):
        return seated(gi, 0)

    def last_el(gi):
        return seated(gi, 1)

    def seat_at(gi, side):
        """(surface index, contact height) where the seat on that side of group gi touches."""
        return seats_of_groups[gi][side][:2]

    # envelope over the whole assembly (hood mouth to the image plane)
    hood = spec.hood
    z_lo = -(hood.length_mm + 50.0 if hood.enabled else 50.0)
    env = Envelope(p, z_lo, p.image_z)

    bore_pts: list[tuple[float, float]] = []
    spacers: list[PartPlan] = []
    retainers: list[PartPlan] = []
    seat_of = spec.seats.element

    def add_spacers(ends, od, ia, ib):
        """Spacers from (front_r, front_z, front_slope, back_r, back_z, back_slope, front part, back part)."""
        for fr, fz, fm, br, bz, bm, pa, pb in ends:
            tube = None
            if bz - fz >= spec.vanes.long_gap_mm:
                t = max(od - spec.spacers.tube_wall_mm, fr, br)
                tube = t if t > max(fr, br) + 1e-6 else None
            sp = Spacer(fr, fz, fm, br, bz, bm, od, tube, spec.spacers.lip_mm)
            name = f"spacer-{len(spacers) + 1}"
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
            spacers.append(PartPlan(name, "spacer", spec.finish_of(name, spec.spacers.finish), sp))
            if pa.startswith("lens"):
                contacts.append(Contact(name, pa, ia, fr, clear[ia]))
            if pb.startswith("lens"):
                contacts.append(Contact(name, pb, ib, br, clear[ib]))

    def outer_diaphragm(z_stop, od, face=None):
        """A diaphragm on a stop in front of the first element or behind the last one (or on its face)."""
        dia = _diaphragm(spec, p, stop, od, z_stop, face)
        parts.append(PartPlan("diaphragm", "diaphragm", spec.finish_of("diaphragm", spec.diaphragm.finish), dia))
        return dia

    def lip_radius(dia, z0, z1, side):
        """Bore of the barrel lip (z0..z1) that clamps an outer diaphragm: clear of the beam."""
        r = max(dia.face_inner_radius(side), env.max_over(z0, z1) + spec.spacers.aperture_margin_mm)
        if dia.outer_radius - r < min_t:
            raise GeometryError(f"the barrel lip holding the diaphragm would be {dia.outer_radius - r:.3f} mm "
                                f"high (minimum {min_t} mm)", field="spacers.aperture_margin_mm",
                                valid="a smaller aperture margin or a larger edge allowance")
        return r

    stop = p.stop_index
    # ---- front seat ---------------------------------------------------------------------
    el0 = first_el(0).template
    i0 = groups[0][0]
    s0, h0 = seat_at(0, 0)
    if stop <= i0:  # a front aperture: barrel lip | diaphragm | spacer | lens 1 (no spacer on lens 1's face)
        od = bores[0] - c_sp
        dia = outer_diaphragm(float(zv[stop]), od, (-1, el0.front_z, radii[0]) if stop == i0 else None)
        fz = lambda r: float(dia.face_z("front", r))  # noqa: E731  (a cone on lens 1's face)
        dz0 = min(fz(dia.inner_radius), fz(od))
        z_front = dz0 - spec.barrel.lip_mm
        r_lip = lip_radius(dia, z_front, max(fz(dia.inner_radius), fz(od)), "front")
        bore_pts += [(r_lip, z_front), (r_lip, fz(r_lip)), (bores[0], fz(bores[0]))]
        if stop < i0:
            dz1 = dia.z_range()[1]
            m = contact_slope(el0.front_z, h0, min(radii[0], od), -1, tangent, wedge)
            hd1 = max(dia.face_inner_radius("rear"), env.max_over(dz1, dz1 + 1.0) + spec.spacers.aperture_margin_mm)
            add_spacers([(hd1, dz1, _EPS_SLOPE, h0, float(el0.front_z(h0)), m, "diaphragm", first_el(0).name)],
                        od, -1, s0)
    elif spec.seats.front == "retainer":
        r_out = bores[0] - c_sp
        m = contact_slope(el0.front_z, h0, min(radii[0], r_out), -1, tangent, wedge)
        ret = Retainer(h0, float(el0.front_z(h0)), m, -1, r_out, spec.retainer.thickness_mm)
        ret.far_r = _opening(env, h0, ret.far_face_z(), ret.contact_z, spec)
        _check_ring(f"retainer-{len(retainers) + 1}", ret.far_r, r_out, min_t)
        name = f"retainer-{len(retainers) + 1}"
        retainers.append(PartPlan(name, "retainer", spec.finish_of(name, spec.retainer.finish), ret))
        contacts.append(Contact(name, first_el(0).name, s0, h0, clear[s0]))
        z_front = ret.far_face_z()
        bore_pts.append((bores[0], z_front))
    else:
        m = contact_slope(el0.front_z, h0, radii[0], -1, tangent, wedge)
        cz = lambda r: float(el0.front_z(h0)) - m * (r - h0)  # noqa: E731
        z_front = cz(bores[0]) - spec.barrel.lip_mm
        bore_pts += [(_opening(env, h0, z_front, cz(h0), spec), z_front), (h0, cz(h0)), (bores[0], cz(bores[0]))]
        contacts.append(Contact("barrel", first_el(0).name, s0, h0, clear[s0]))

    # ---- gaps between groups --------------------------------------------------------------
    stop_placed = stop <= i0 or stop >= groups[-1][-1]
    for gi in range(len(groups) - 1):
        A, B = last_el(gi), first_el(gi + 1)
        ia, ib = groups[gi][-1], groups[gi + 1][0]
        (sa, hA), (sb, hB) = seat_at(gi, 1), seat_at(gi + 1, 0)   # where the seats touch (ia, ib unless stepped)
        RA, RB = radii[gi], radii[gi + 1]
        stop_here = ia <= stop <= ib
        element_no = int(lens_parts[gi + 1][0].name.split("-")[1])   # the group's first element
        seat = "spacer" if stop_here else seat_of.get(element_no, spec.seats.default)
        if seat == "retainer":  # a barrel shoulder behind A, a retainer ring in front of B
            mA = contact_slope(A.template.back_z, hA, RA, +1, tangent, wedge)
            cA = lambda r, z0=float(A.template.back_z(hA)), m=mA, h=hA: z0 + m * (r - h)  # noqa: E731
            r_out = bores[gi + 1] - c_sp
            mB = contact_slope(B.template.front_z, hB, min(RB, r_out), -1, tangent, wedge)
            ret = Retainer(hB, float(B.template.front_z(hB)), mB, -1, r_out, spec.retainer.thickness_mm)
            ret.far_r = _opening(env, hB, ret.far_face_z(), ret.contact_z, spec)
            name = f"retainer-{len(retainers) + 1}"
            _check_ring(name, ret.far_r, r_out, min_t)
            # the shoulder's rear face: a lip's thickness behind A, clear of the ring's far face
            z_sh = max(cA(bores[gi]), cA(hA)) + spec.barrel.lip_mm
            room = ret.far_face_z() - c_glass - z_sh
            if room < 0:
                raise GeometryError(
                    f"no room for a shoulder behind {A.name} and a retainer in front of {B.name}: "
                    f"{-room:.3f} mm short", field=f"seats.element.{element_no}",
                    valid="'spacer' or 'shoulder', a thinner retainer or barrel lip, or a larger air gap")
            r_sh = _opening(env, hA, z_sh, cA(hA), spec)
            if bores[gi + 1] - r_sh < min_t:
                raise GeometryError(f"the shoulder behind {A.name} would be {bores[gi + 1] - r_sh:.3f} mm high "
                                    f"(minimum {min_t} mm)", field=f"seats.element.{element_no}",
                                    valid="'spacer', or a larger edge allowance")
            retainers.append(PartPlan(name, "retainer", spec.finish_of(name, spec.retainer.finish), ret))
            bore_pts += [(bores[gi], cA(bores[gi])), (hA, cA(hA)), (r_sh, z_sh), (bores[gi + 1], z_sh)]
            contacts += [Contact("barrel", A.name, sa, hA, clear[sa]), Contact(name, B.name, sb, hB, clear[sb])]
            continue
        if seat == "glass":
            bore_pts += _glass_seat(A, B, RA, RB, bores[gi], bores[gi + 1], c_glass, element_no)
            # the rim corner that rests on the other face; that face is touched where no light
            # reaches it (the envelope there), which may lie inside the file's semi-diameter
            small, big, i_big = (A, B, ib) if RA < RB else (B, A, ia)
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
            contacts.append(Contact(small.name, big.name, i_big, rim, min(light, clear[i_big])))
            if rim < light + BEAM_CLEAR_MM:
                raise GeometryError(
                    f"{small.name} would rest on {big.name} at r = {rim:.3f} mm, inside the beam there "
                    f"({light:.3f} mm)", field=f"seats.element.{element_no}", valid="'spacer' or 'shoulder'")
            continue
        if seat == "shoulder":
            mA = contact_slope(A.template.back_z, hA, RA, +1, tangent, wedge)
            mB = contact_slope(B.template.front_z, hB, RB, -1, tangent, wedge)
            cA = lambda r, z0=float(A.template.back_z(hA)), m=mA, h=hA: z0 + m * (r - h)  # noqa: E731
            cB = lambda r, z0=float(B.template.front_z(hB)), m=mB, h=hB: z0 - m * (r - h)  # noqa: E731
            rr = np.linspace(max(hA, hB), min(bores[gi], bores[gi + 1]), 50)
            thick = float(np.min([cB(r) - cA(r) for r in rr]))
            if thick < min_t:
                raise GeometryError(
                    f"the barrel shoulder between {A.name} and {B.name} is {thick:.3f} mm thick "
                    f"(minimum {min_t} mm)", field=f"seats.element.{element_no}",
                    valid="'spacer', or a larger air gap")
            bore_pts += [(bores[gi], cA(bores[gi])), (hA, cA(hA)), (hB, cB(hB)), (bores[gi + 1], cB(bores[gi + 1]))]
            contacts += [Contact("barrel", A.name, sa, hA, clear[sa]), Contact("barrel", B.name, sb, hB, clear[sb])]
            continue
        od = min(bores[gi], bores[gi + 1]) - c_sp
        mA = contact_slope(A.template.back_z, hA, min(RA, od), +1, tangent, wedge)
        mB = contact_slope(B.template.front_z, hB, min(RB, od), -1, tangent, wedge)
        ends = []  # (front_r, front_z, front_slope, back_r, back_z, back_slope, front part, back part)
        if stop_here:
            ds = spec.diaphragm
            faces = {ia: (+1, A.template.back_z, RA), ib: (-1, B.template.front_z, RB)}
            # a stop on A's rear or B's front face: the plate follows that face; a stop plane with
            # no room for a spacer between it and A (B): the plate follows A's (B's) face up to it
            hug = stop if stop in faces else None
            while True:
                dia = _diaphragm(spec, p, stop, od, float(zv[stop]), faces.get(hug))
                ends = _diaphragm_spacer_ends(dia, env, spec, od, hug, ia, ib, (hA, mA, A), (hB, mB, B))
                short = [ia if e[7] == "diaphragm" else ib for e in ends
                         if Spacer(*e[:6], od).min_length() < min_t]
                if hug is not None or not short:
                    break
                hug = short[0]
            stop_placed = True
            parts.append(PartPlan("diaphragm", "diaphragm", spec.finish_of("diaphragm", ds.finish), dia))
        else:
            ends.append((hA, float(A.template.back_z(hA)), mA, hB, float(B.template.front_z(hB)), mB, A.name, B.name))
        add_spacers(ends, od, sa, sb)
        # barrel steps where the glass outside the spacer ends
        r_in = od + c_sp
        # (clear of the glass by c_glass: the step does not hold the lens, and a step face
        # through the glass's corner would leave a sub-micrometre sliver beside it)
        za = float(A.template.back_z(_radii(min(r_in, RA), RA, A.template.back_chamfer)).max()) + c_glass
        zb = float(B.template.front_z(_radii(min(r_in, RB), RB, B.template.front_chamfer)).min()) - c_glass
        if zb < za:
            raise GeometryError(f"the barrel cannot step between {A.name} and {B.name}: their edges overlap "
                                f"axially by {za - zb:.3f} mm", field="lens_edge.allowance_mm",
                                valid="a smaller edge allowance")
        bore_pts += [(bores[gi], za), (r_in, za), (r_in, zb), (bores[gi + 1], zb)]
    if not stop_placed:
        raise GeometryError(
            f"the stop (surface {stop + 1}) lies inside a cemented group, where no diaphragm fits; "
            "the mount layout needs it in an air gap or on a group's outer face", field=f"surface[{stop + 1}]",
            valid="a stop in an air gap (between two lens groups, in front of the first or behind the last) "
                  "or on the outer face of a lens group")

    # ---- rear seat ----------------------------------------------------------------------
    gl = len(groups) - 1
    elL = last_el(gl)
    iL = groups[gl][-1]
    sL, hL = seat_at(gl, 1)
    if stop >= iL:  # a rear stop: lens L | spacer | diaphragm | barrel lip (no spacer on lens L's face)
        od = bores[gl] - c_sp
        dia = outer_diaphragm(float(zv[stop]), od, (+1, elL.template.back_z, radii[gl]) if stop == iL else None)
        rz = lambda r: float(dia.face_z("rear", r))  # noqa: E731  (a cone on lens L's face)
        dz1 = max(rz(dia.inner_radius), rz(od))
        z_back = dz1 + spec.barrel.lip_mm
        r_lip = lip_radius(dia, min(rz(dia.inner_radius), rz(od)), z_back, "rear")
        if stop > iL:
            dz0 = dia.z_range()[0]
            m = contact_slope(elL.template.back_z, hL, min(radii[gl], od), +1, tangent, wedge)
            hd0 = max(dia.face_inner_radius("front"), env.max_over(dz0 - 1.0, dz0) + spec.spacers.aperture_margin_mm)
            add_spacers([(hL, float(elL.template.back_z(hL)), m, hd0, dz0, _EPS_SLOPE, elL.name, "diaphragm")],
                        od, sL, -1)
        bore_pts += [(bores[gl], rz(bores[gl])), (r_lip, rz(r_lip)), (r_lip, z_back)]
    elif spec.seats.rear == "shoulder":
        m = contact_slope(elL.template.back_z, hL, radii[gl], +1, tangent, wedge)
        cz = lambda r: float(elL.template.back_z(hL)) + m * (r - hL)  # noqa: E731
        z_back = cz(bores[gl]) + spec.barrel.lip_mm
        bore_pts += [(bores[gl], cz(bores[gl])), (hL, cz(hL)), (_opening(env, hL, z_back, cz(hL), spec), z_back)]
        contacts.append(Contact("barrel", elL.name, sL, hL, clear[sL]))
    else:
        r_out = bores[gl] - c_sp
        m = contact_slope(elL.template.back_z, hL, min(radii[gl], r_out), +1, tangent, wedge)
        ret = Retainer(hL, float(elL.template.back_z(hL)), m, +1, r_out, spec.retainer.thickness_mm)
        ret.far_r = _opening(env, hL, ret.far_face_z(), ret.contact_z, spec)
        _check_ring(f"retainer-{len(retainers) + 1}", ret.far_r, r_out, min_t)
        name = f"retainer-{len(retainers) + 1}"
        retainers.append(PartPlan(name, "retainer", spec.finish_of(name, spec.retainer.finish), ret))
        contacts.append(Contact(name, elL.name, sL, hL, clear[sL]))
        z_back = ret.far_face_z()
        bore_pts.append((bores[gl], z_back))

    r_barrel = max(r for r, _ in bore_pts) + spec.barrel.wall_mm
    barrel = Barrel(tuple((float(r), float(z)) for r, z in bore_pts), float(r_barrel))
    parts.insert(0, PartPlan("barrel", "barrel", spec.finish_of("barrel", spec.barrel.finish), barrel))

    # ---- hood, vanes, detector housing (lensmount.cad.baffles) ---------------------------
    from lensmount.cad.baffles import hood_and_vanes, housing

    rho = np.linspace(0.0, clear[i0], APERTURE_SAMPLES)
    aperture = (rho, el0.front_z(rho))  # the entrance aperture: the first surface over its clear aperture
    hood_part, vane_parts = hood_and_vanes(spec, env, z_front, r_barrel, bore_pts[0][0], spacers, notes,
                                           aperture, spec.exclusion_deg(p.max_field_deg))
    housing_part, rear_baffle = housing(spec, env, p.image_z, z_back, r_barrel, bore_pts[-1][0], notes)

    ordered = [parts[0]] + [pp for grp in lens_parts for pp in grp] + retainers + spacers + parts[1:]
    if hood_part:
        ordered.append(hood_part)
    ordered += vane_parts
    if housing_part:
        ordered.append(housing_part)
    if rear_baffle:
        ordered.append(rear_baffle)
    return Layout(p, ordered, contacts, env, notes)


__all__ = ["PartPlan", "Layout", "Envelope", "Contact", "plan", "contact_slope", "pupil_edge_radius"]
