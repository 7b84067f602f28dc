"""Lens elements of a group as the mount holds them: flat bevels, stepped cemented elements, and where
the group's seats touch it (shared by the layout planner and `lensmount init`'s starter mount).

* An element whose edge would be thinner than the minimum gets a flat bevel on an outer face that
  closes in toward the rim (a thin meniscus); so does a deep outer face whose sphere ends inside the
  rim (as OpticStudio draws it); `lens_edge.flat_faces` grinds listed faces flat anyway.
* An outer element of a cemented group too thin at the group's rim even so (a thin-edged crown) is
  stepped: edged to its clear semi-diameter plus a bevel, inside its partner's rim; the seat then
  touches the partner's cemented face outside it (`templates.lens_element.GroupOutline`), which is
  ground there (role `bevel`: the tracer's analytic cemented interface ends at the step).
"""

from __future__ import annotations

from dataclasses import replace

from lensmount.optics.prescription import Prescription
from lensmount.templates.lens_element import GroupOutline, LensElement, OpticalFace


def lens_element(fa: OpticalFace, fb: OpticalFace, R: float, bf: float, bb: float, clear_a: float | None,
                 clear_b: float | None, min_t: float) -> LensElement:
    """The element between faces fa and fb, radius R; where its edge would be thinner than min_t, each
    outer face (clear_a / clear_b given) that closes in toward the rim gets a flat bevel from its clear
    semi-diameter out, when that makes the edge thick enough (a thin meniscus: the optics end at the
    clear aperture, the ground flat carries the seat)."""
    el = LensElement(fa, fb, R, bf, bb)
    short = [not ends_inside(f, R) for f in (fa, fb)]   # a deep face whose sphere ends inside the rim
    if el.edge_thickness() >= min_t and not any(short):
        return el
    front = clear_a if clear_a is not None and clear_a < R - bf and (
        short[0] or float(fa.z(R)) > float(fa.z(clear_a))) else None
    back = clear_b if clear_b is not None and clear_b < R - bb and (
        short[1] or float(fb.z(R)) < float(fb.z(clear_b))) else None
    flat = LensElement(fa, fb, R, bf, bb, front, back)
    return flat if (front is not None or back is not None) and flat.edge_thickness() >= min_t else el


def ends_inside(face: OpticalFace, r: float) -> bool:
    """The face's profile exists out to radius r (a sphere or ellipsoid ends at its reach, where it
    turns parallel to the axis: no glass follows it beyond)."""
    return r <= face.profile.max_radius()


def face_beyond_reach(el: LensElement) -> OpticalFace | None:
    """An optical face of el that its outline follows beyond where the face exists (None: all exist
    where they are followed). The outline follows a face to the rim or to its flat bevel."""
    for face, flat in ((el.front, el.front_flat_from), (el.back, el.back_flat_from)):
        if not ends_inside(face, el.outer_radius if flat is None else min(flat, el.outer_radius)):
            return face
    return None


def thin_plate(faces: list[OpticalFace], min_t: float) -> bool:
    """The group is one plane-parallel plate thinner than the minimum (a 0.17 mm cover glass): its
    thickness is the lens file's, the same out to its rim, so the minimum, which guards an edge that
    curvature and chamfers thin, does not apply, and no chamfer is cut on it (a cover slip has none)."""
    return len(faces) == 2 and all(f.profile.is_plane for f in faces) and \
        abs(faces[1].z_vertex - faces[0].z_vertex) < min_t


def lens_group(faces: list[OpticalFace], R: float, chamfer: float, clear: list[float], min_t: float,
               stepped_min: float, flat: tuple[bool, bool] = (False, False)) -> tuple[list[LensElement], tuple[int, ...]]:
    """The elements of one lens group (faces and clear semi-diameters front to back), radius R, and
    the positions of its stepped elements.

    An outer element of a cemented group that is too thin at R even with a flat bevel (a thin-edged
    crown) is stepped: edged to its clear aperture plus a bevel (the chamfer, smaller where the edge
    would else be under `stepped_min`), inside its partner's rim. It carries no seat; the cement
    holds it, and the group is seated on the partner's cemented face outside it, which gets the
    protective chamfer at its rim (`seat_of_group`). `flat`: grind the group's front (back) face flat
    from its clear semi-diameter out (lens_edge.flat_faces)."""
    if thin_plate(faces, min_t):
        return [LensElement(faces[0], faces[1], R, 0.0, 0.0)], ()
    n = len(faces) - 1
    els = [lens_element(faces[k], faces[k + 1], R, chamfer if k == 0 else 0.0, chamfer if k == n - 1 else 0.0,
                        clear[k] if k == 0 else None, clear[k + 1] if k == n - 1 else None, min_t) for k in range(n)]
    if flat[0] and clear[0] < R - els[0].front_chamfer:
        els[0] = replace(els[0], front_flat_from=clear[0])
    if flat[1] and clear[-1] < R - els[-1].back_chamfer:
        els[-1] = replace(els[-1], back_flat_from=clear[-1])
    stepped: list[int] = []
    for k, partner, front in ((0, 1, True), (n - 1, n - 2, False)):
        if n < 2 or els[k].edge_thickness() >= min_t or partner in stepped:
            continue
        small = _stepped(faces[k], faces[k + 1], max(clear[k], clear[k + 1]), chamfer, front, stepped_min)
        if small is None:
            continue
        els[k] = small
        # the partner's cemented face outside the step: bare glass, ground like an edge, with the chamfer
        rim = small.outer_radius
        els[partner] = replace(els[partner], **({"front_chamfer": chamfer, "front_ground_from": rim} if front
                                                else {"back_chamfer": chamfer, "back_ground_from": rim}))
        stepped.append(k)
    return els, tuple(stepped)


def _stepped(fa: OpticalFace, fb: OpticalFace, clear: float, chamfer: float, front: bool,
             stepped_min: float) -> LensElement | None:
    """The element edged at its clear semi-diameter plus a bevel b <= chamfer on its outer face (none
    on the cemented one), b as large as keeps the edge >= stepped_min; None if even b = 0 does not."""
    def element(b: float) -> LensElement:
        return LensElement(fa, fb, clear + b, b if front else 0.0, 0.0 if front else b)

    if element(0.0).edge_thickness() < stepped_min:
        return None
    if element(chamfer).edge_thickness() >= stepped_min:
        return element(chamfer)
    lo, hi = 0.0, chamfer
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if element(mid).edge_thickness() >= stepped_min else (lo, mid)
    return element(lo)


def seat_of_group(elements: list, stepped: tuple[int, ...], group: tuple[int, ...], clear: list[float],
                  margin: float) -> tuple[tuple[int, float, object], tuple[int, float, object]]:
    """Where the seats touch a lens group, front and back: (surface index, contact height, outline
    whose front_z / back_z the seat follows). Normally the outer faces at the clear semi-diameter
    plus the contact margin; beside a stepped element, the partner's cemented face at the stepped
    rim plus the margin (the light there stays inside the stepped element's clear aperture)."""
    n = len(elements)
    outline = GroupOutline(tuple(elements)) if stepped else None
    front = (group[1], elements[0].outer_radius + margin, outline) if 0 in stepped else \
        (group[0], clear[group[0]] + margin, outline or elements[0])
    back = (group[-2], elements[-1].outer_radius + margin, outline) if n - 1 in stepped else \
        (group[-1], clear[group[-1]] + margin, outline or elements[-1])
    return front, back


def group_rim(p: Prescription, group: tuple[int, ...], first: int, edge) -> float:
    """Mechanical semi-diameter (mm) of a lens group whose first element is number `first`: the largest
    `lens_edge.semi_diameter_mm` of its elements, else the largest of the file's mechanical
    semi-diameters (clear + `allowance_mm` where the file gives none). `p` has its clear semi-diameters."""
    given = edge.semi_diameter_mm
    overrides = [given[first + k] for k in range(len(group) - 1) if first + k in given]
    if overrides:
        return float(max(overrides))
    surf = p.surfaces
    return float(max(surf[i].mechanical_semi_diameter if surf[i].mechanical_semi_diameter is not None
                     else float(surf[i].clear_semi_diameter) + edge.allowance_mm for i in group))


__all__ = ["group_rim", "lens_element", "lens_group", "thin_plate", "seat_of_group", "ends_inside", "face_beyond_reach"]
