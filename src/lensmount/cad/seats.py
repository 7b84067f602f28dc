"""Seats: where a ring, a spacer, the barrel or the diaphragm meets the glass, in the (r, z) half plane.

The geometry `cad.layout` places each seat with: the cone of an end face that touches a surface
at one height and stays off the glass elsewhere (`contact_slope`), a ring's bore opened where the
beam grows, the diaphragm whose land passes the designed entrance pupil (on a stop plane or
following a lens face), the spacers either side of it, and the barrel step where one lens rests
on another.
"""

from __future__ import annotations

import numpy as np

from lensmount.cad.plan import Envelope
from lensmount.design.mount import MountSpec
from lensmount.errors import GeometryError
from lensmount.optics.apertures import beam_envelope
from lensmount.optics.prescription import Prescription
from lensmount.optics.realrays import axial_rim_ray
from lensmount.templates.diaphragm import Diaphragm

_SLOPE_SAMPLES = 256
EPS_SLOPE = 1e-6  # keeps a contact a line, not a face, against rounding


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
        return (along if along >= need else sharp) + EPS_SLOPE
    return sharp + EPS_SLOPE


def ring_opening(env: Envelope, h: float, z_far: float, z_contact: float, spec: MountSpec) -> float:
    """Bore radius at a ring's far face: the contact radius, or wider where the beam grows.

    The bore runs straight from (h, z_contact) to (r, z_far); the beam is convex in z
    in air, so clearing both ends (with the spacer margin) clears the whole bore.
    """
    beam = env.max_over(min(z_far, z_contact), max(z_far, z_contact))
    return float(max(h, beam + spec.spacers.aperture_margin_mm if beam > h else h))


def check_ring_wall(name: str, bore: float, outside: float, min_t: float) -> None:
    if outside - bore < min_t:
        raise GeometryError(
            f"{name}: its bore must open to {bore:.3f} mm to clear the beam, leaving a wall of "
            f"{outside - bore:.3f} mm inside its outside radius {outside:.3f} mm (minimum {min_t} mm)",
            field="retainer.thickness_mm", valid="a thinner ring, a smaller aperture margin or a larger lens")


def radii_to_rim(lo: float, R: float, chamfer: float) -> np.ndarray:
    """Radii from lo to R including the chamfer's corner (where the glass's z peaks)."""
    rs = np.linspace(lo, R, 129)
    return np.unique(np.concatenate([rs, [R - chamfer] if R - chamfer >= lo else []]))


def pupil_edge_radius(prescription: Prescription, z0: float, z1: float) -> float:
    """Largest radius, for z in [z0, z1], of the on-axis ray entering at the designed EPD/2.

    A diaphragm whose bore is this radius over its land passes exactly the designed
    entrance pupil (primary wavelength), wherever the land sits: on a dummy stop plane,
    or next to a curved stop surface where the paraxial stop height no longer applies.
    """
    if prescription.object_telecentric:   # the object-space NA is the aperture: the stop passes every field's beam
        return float(beam_envelope(prescription, np.linspace(z0, z1, 9)).max())
    rays = axial_rim_ray(prescription)   # from a finite object: from the axial object point
    pts = np.concatenate([rays.origins[None], rays.points], axis=0)[:, 0]  # (S+2, 3) polyline
    zs = np.linspace(z0, z1, 9)
    return float(np.interp(zs, pts[:, 2], np.abs(pts[:, 1])).max())


def stop_diaphragm(spec, p, stop, od, z_stop, face=None) -> Diaphragm:
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
            m = side * (max(0.0, need) + EPS_SLOPE)
        lo = zc - 0.5 * land
        r0 = pupil_edge_radius(p, lo, lo + land)
    return Diaphragm(zc, r0, *args, slope=m)


def diaphragm_spacer_ends(dia, env, spec, od, hug, ia, ib, a, b) -> list[tuple]:
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
                     EPS_SLOPE - dia.slope, A.name, "diaphragm"))
    if hug != ib:
        ends.append((hd1, float(dia.face_z("rear", hd1)), dia.slope + EPS_SLOPE, hB,
                     float(B.template.front_z(hB)), mB, "diaphragm", B.name))
    return ends


BEAM_CLEAR_MM = 0.01  # a glass seat's contact at least this far outside the light


def glass_seat_bore(A, B, RA, RB, bore_a, bore_b, c_glass, element_no) -> list[tuple[float, float]]:
    """Barrel bore points where lens A and lens B sit on each other (seat "glass"): the bore steps
    from the smaller element's to the larger's `c_glass` clear of the larger's glass outside the
    smaller's bore; the smaller element's edge cylinder must start before that step (the bore holds it)."""
    if RA < RB:   # A nests into B's front: step just in front of B's glass outside A's bore
        rs = radii_to_rim(min(bore_a, RB), RB, B.template.front_chamfer)
        z = float(B.template.front_z(rs).min()) - c_glass
        inside = z > A.template.edge_z()[0]
    else:         # B nests into A's rear
        rs = radii_to_rim(min(bore_b, RA), RA, A.template.back_chamfer)
        z = float(A.template.back_z(rs).max()) + c_glass
        inside = z < B.template.edge_z()[1]
    if not inside:
        raise GeometryError(f"{A.name} and {B.name} cannot sit on each other: the barrel step between their "
                            "bores would pass the smaller one's whole edge", field=f"seats.element.{element_no}",
                            valid="'spacer' or 'shoulder'")
    return [(bore_a, z), (bore_b, z)]


__all__ = ["contact_slope", "ring_opening", "check_ring_wall", "radii_to_rim", "pupil_edge_radius",
           "stop_diaphragm", "diaphragm_spacer_ends", "BEAM_CLEAR_MM", "glass_seat_bore", "EPS_SLOPE"]
