"""A starting mount.toml, finishes.toml and case-2 scene derived from a lens (`lensmount init DIR --lens FILE`).

The shipped examples' mount.toml fit their own lens only (the Cooke triplet's 0.5 mm
edge allowance leaves a thin crown with no edge on another lens). Here every
dimension follows from the lens itself, in the mount layer's own keys
(docs/mount-toml.md):

- metal thicknesses (barrel wall, lips, retainer, housing wall) scale with the
  largest clear semi-diameter a, within what a machinist can turn (0.5-4 mm); so does
  the thinnest part allowed ([checks], 0.2 mm on a lens under 10 mm across, else 0.3);
- each element's mechanical semi-diameter is its clear semi-diameter plus the edge
  allowance, cut back where the element's edge would be thinner than a quarter of its
  centre (a meniscus or a strong positive lens) or where it would meet its
  neighbour's edge across the air gap; where a spacer could not reach both
  neighbours' contacts, a barrel shoulder seats the element (similar contact heights)
  or a shoulder behind the one and a ring in front of the other (far apart); where two
  faces meet outside the smaller element's clear aperture plus contact margin (and not
  at the diaphragm), the smaller element ends there and rests on the other (seat "glass");
  an element too thin at every such rim gets a flat bevel (`cad.lens_groups.lens_element`) and
  the rim where that makes it thick enough; a cemented group's thin-edged outer element
  is stepped (`cad.lens_groups.lens_group`: edged to its clear aperture, the group seated on its
  partner), and where nothing else builds, the faces beside the stop that curl toward it
  are ground flat from their clear aperture (`lens_edge.flat_faces`); so are a larger
  element's face that curls past its smaller neighbour's rim (nested: no barrel step fits
  between them) and both faces of an air gap the import clipped where they cross
  (design.edges); an element whose faces cross inside its rim keeps its rim (its flat
  bevels carry the edge), and one held by a ring is wide enough for the ring's wall above
  the beam; where the planner refuses the mount, its alternatives are tried where the refusal
  points (cad.mount_search: seats, rims, flat faces, margins), then every rim enlarged together by
  one margin over its clear aperture (`rim_margins`: the file's rims set aside, as an engineer does
  where they all sit too close to the light for a chamfer and a seat), and `init` refuses the lens
  when none builds;
- the hood shades the first lens from the sun at the exclusion angle when that takes
  at most two entrance diameters, else it stops there; its bore is the beam at the
  mouth plus room for vanes; one vane per bay as long as the hood's bore is wide;
- the housing's detector is a 3:2 frame inscribed in the image circle (real chief
  ray of the largest field);
- a lens with mirrors gets cells in a straight barrel (lensmount.cad.catadioptric),
  with the same wall, lip, margin and allowance rules and no hood or housing yet.

The finishes (the design's, `starter_finishes`) are the seed paper's case 2: every mount face
and lens edge Lambertian 5 %, the diaphragm edge absorbing, and a mirror's coated face a
polished mirror's scatter; the case-2 scene (the test condition) is the sun 5° outside the
field on that detector, or for a finite object a bright point on its plane 5° outside the field; a
finite object also gets the object-lambertian scene (the object field itself, its direct image on).
"""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np

from lensmount.cad.lens_groups import group_rim, lens_group, seat_of_group, thin_plate
from lensmount.cad.mount_search import find_mount
from lensmount.cad.plan import Envelope
from lensmount.design.mount import LensEdge, MountSpec
from lensmount.optics.paraxial import object_height_at, paraxial
from lensmount.optics.prescription import Prescription
from lensmount.optics.profiles import Profile
from lensmount.optics.realrays import image_height
from lensmount.design.finishes import surface_rule
from lensmount.templates.lens_element import LensElement, OpticalFace

SUN_MARGIN_DEG = 5.0         # the sun this far outside the field (as [hood] exclusion_deg's default)
MIN_EDGE_FRACTION = 0.25     # edge thickness at least this fraction of the centre thickness
MAX_HOOD_DIAMETERS = 2.0     # hood length at most this many entrance diameters


def _clamp(x: float, lo: float, hi: float) -> float:
    return float(min(max(x, lo), hi))


def _round(x: float, digits: int = 2) -> float:
    return float(round(x, digits))


def detector_size(p: Prescription) -> tuple[float, float]:
    """A 3:2 detector whose corners lie on the image circle (width, height), mm; a lens
    with no field gets one a fifth of the exit beam wide."""
    y = image_height(p)
    if y <= 0.0:
        side = max(0.2 * paraxial(p).exit_pupil_diameter, 1.0)
        return _round(side), _round(side)
    return _round(2 * y * 3 / math.sqrt(13)), _round(2 * y * 2 / math.sqrt(13))


def _edges_and_seats(p: Prescription, allowance: float, chamfer: float, contact: float, min_thickness: float,
                     retainer: float, margin: float, widen: bool
                     ) -> tuple[dict[int, float], dict[int, str], tuple[int, ...]]:
    """Element number → mechanical semi-diameter where clear + allowance would not do,
    element number → seat where a spacer could not reach both neighbours' contacts, and the
    1-based faces to grind flat (two neighbours' faces that meet across the air inside both rims).
    `widen`: there, widen the smaller edge for a spacer (unless that makes it too thin)
    rather than seat the element on a shoulder or ring.

    Never below clear + contact margin + chamfer (the seat must touch the glass inside
    its edge), nor below a spacer wall above the contacts at the diaphragm's gap, nor
    below the front retainer's wall above the beam: a lens that is too thin even there
    is left to `regenerate` to report (the lens file's own edge is).
    """
    surf, zv = p.surfaces, p.vertex_z
    clear = [float(s.clear_semi_diameter) for s in surf]

    def face(i: int) -> OpticalFace:
        return OpticalFace.of(i, float(zv[i]), surf[i])

    step = 0.05 * allowance
    groups = p.lens_groups()

    stepped_min = LensEdge().stepped_min_edge_mm

    def group(k: int, r: float, flats: tuple[bool, bool] = (False, False)):
        """The layout's own elements: flat bevels and stepped elements included."""
        g = groups[k]
        return lens_group([face(i) for i in g], r, chamfer, [clear[i] for i in g], min_thickness, stepped_min, flats)

    def thin(k: int, r: float) -> bool:   # a stepped element's edge does not follow the group's rim
        g, stepped = groups[k], group(k, r)[1]
        if thin_plate([face(i) for i in g], min_thickness):
            return False
        return any(LensElement(face(a), face(b), r, chamfer, chamfer).edge_thickness()
                   < max(min_thickness, MIN_EDGE_FRACTION * (zv[b] - zv[a]))
                   for j, (a, b) in enumerate(zip(g[:-1], g[1:])) if j not in stepped)

    def crossed(k: int, r: float) -> bool:   # faces meet inside r: edged by a flat bevel (an import clip)
        g = groups[k]
        return any(LensElement(face(a), face(b), r).edge_thickness() < 0.0 for a, b in zip(g[:-1], g[1:]))

    def too_thin(k: int, r: float) -> bool:
        els, stepped = group(k, r)
        if thin_plate([face(i) for i in groups[k]], min_thickness):
            return False
        return any(el.edge_thickness() < min_thickness for j, el in enumerate(els) if j not in stepped)

    def seat_heights(k: int, r: float) -> tuple[float, float]:   # (front, back) contact heights
        front, back = seat_of_group(*group(k, r), groups[k], clear, contact)
        return front[1], back[1]

    numbers = np.cumsum([0] + [len(g) - 1 for g in groups])[:-1] + 1   # first element of each group
    natural = [max(clear[i] for i in g) + allowance for g in groups]
    # the glass the lens file gives (a catalogue part's diameter: a MEMA, or a fixed DIAM that bounds the
    # glass, optics.io.zemax) is the part one buys: its rim stays, and regenerate judges the seats on it
    given = {k: group_rim(p, g, int(first), LensEdge(allowance_mm=allowance)) for k, (g, first) in
             enumerate(zip(groups, numbers)) if any(surf[i].mechanical_semi_diameter is not None for i in g)}
    natural = [given.get(k, n) for k, n in enumerate(natural)]
    # the seat's contact inside the chamfer (beside a stepped element: on its partner, outside its rim)
    floor = [max(max(seat_heights(k, n)) + chamfer + 0.01, max(clear[i] for i in g) + contact + chamfer + 0.01)
             for k, (g, n) in enumerate(zip(groups, natural))]
    seats = {}
    radii_fixed = dict(given)
    flat: set[int] = set()   # 1-based faces to grind flat (lens_edge.flat_faces)
    stop = p.stop_index
    for k in range(len(groups) - 1):
        ia, ib = groups[k][-1], groups[k + 1][0]
        wall = max(seat_heights(k, natural[k])[1], seat_heights(k + 1, natural[k + 1])[0]) + min_thickness + 0.02
        meet = _faces_meet(face(ia), face(ib), min(clear[ia], clear[ib]) + contact, max(natural[k], natural[k + 1]))
        if meet is not None and clear[ia] == clear[ib] and meet < min(natural[k], natural[k + 1]):
            # faces the import clipped where they cross across the air (design.edges: both to one
            # height, 1.3 mm apart there), inside both rims: both are ground flat from there out
            flat |= {ia + 1, ib + 1}
            continue
        # nested: at their smallest or their natural rims the larger element's face beyond the smaller's
        # rim reaches past that rim along the axis, so no barrel step fits between them
        nested = [_step_blocked(group(k, r[k])[0][-1], group(k + 1, r[k + 1])[0][0]) for r in (floor, natural)]
        if wall <= min(natural[k], natural[k + 1]) and not any(nested):
            continue
        small = k if natural[k] <= natural[k + 1] else k + 1
        if not ia <= stop <= ib and meet is not None and small not in radii_fixed \
                and floor[small] <= meet + chamfer <= natural[small] + chamfer:
            # the faces meet just outside the light: the smaller element rests its rim there on the
            # other's face (compact camera lenses), its chamfer starting where they meet
            radii_fixed[small] = floor[small] = meet + chamfer
            seats[int(numbers[k + 1])] = "glass"
            continue
        big_is_a = small != k
        if any(nested) and not any(_step_blocked(group(k, r[k], (False, big_is_a))[0][-1],
                                                 group(k + 1, r[k + 1], (not big_is_a, False))[0][0])
                                   for r in (floor, natural)):
            # the larger element's face curls past the smaller one's rim (a meniscus inside a deep
            # concave face): ground flat from its clear semi-diameter out, it leaves the barrel room
            flat.add((ia if big_is_a else ib) + 1)
        if ia <= stop <= ib or (widen and not any(thin(j, wall) for j in (k, k + 1) if natural[j] < wall)):
            # widen the smaller edge(s) so that a spacer fits (the diaphragm's gap always has spacers)
            floor[k], floor[k + 1] = max(floor[k], wall), max(floor[k + 1], wall)
        elif abs(clear[ia] - clear[ib]) < allowance:   # a barrel shoulder steps from one bore to the other
            seats[int(numbers[k + 1])] = "shoulder"
        else:   # contacts far apart in height: a shoulder behind A, a ring in front of B
            seats[int(numbers[k + 1])] = "retainer"

    def above_the_ring(i: int) -> float:   # a retainer's wall in front of face i stands above the beam there
        zc = float(face(i).z(min(clear[i] + contact, face(i).profile.max_radius())))   # a hemisphere ends there
        beam = Envelope(p, zc - retainer - 1.0, zc, step=0.1).max_over(zc - retainer - 1.0, zc)
        return beam + margin + min_thickness + 0.02

    i0 = groups[0][0]
    if stop >= i0:  # a retainer holds element 1
        floor[0] = max(floor[0], above_the_ring(i0))
    for k in range(1, len(groups)):
        if seats.get(int(numbers[k])) == "retainer":
            floor[k] = max(floor[k], above_the_ring(groups[k][0]))
    radii = [radii_fixed.get(k, max(n, f)) for k, (n, f) in enumerate(zip(natural, floor))]
    for k in range(len(groups)):   # thick enough at the edge
        while k not in given and radii[k] - step >= floor[k] and thin(k, radii[k]) and not crossed(k, radii[k]):
            radii[k] -= step
        if too_thin(k, radii[k]) and k not in radii_fixed:   # a flat-bevelled meniscus thickens outward
            wider = [r for r in np.arange(radii[k], 1.5 * max(clear[i] for i in groups[k]), step)
                     if not too_thin(k, r)]
            radii[k] = wider[0] if wider else radii[k]
    for k in range(len(groups) - 1):      # room for the barrel's step between neighbouring edges
        ia, ib = groups[k][-1], groups[k + 1][0]
        if seats.get(int(numbers[k + 1])) == "glass" or ia + 1 in flat:
            continue
        for _ in range(40):
            r = min(radii[k], radii[k + 1])
            a, b = group(k, radii[k])[0][-1], group(k + 1, radii[k + 1])[0][0]   # as built: flat bevels too
            if float(b.face_z(True, r) - a.face_z(False, r)) > min_thickness + 2 * chamfer and not _step_blocked(a, b):
                break
            big = k if radii[k] >= radii[k + 1] else k + 1
            if radii[big] - step < floor[big] or big in given:
                break
            radii[big] -= step
    out = {}
    for g, first, r in zip(groups, numbers, radii):
        # written wherever the layout would take another rim: the file's own mechanical semi-diameter
        # may be the clear one (OpticStudio writes its automatic one), leaving no room for a seat
        if abs(r - group_rim(p, g, int(first), LensEdge(allowance_mm=allowance))) > 1e-9:
            for k in range(len(g) - 1):
                out[int(first) + k] = _round(r, 3)
    return out, seats, tuple(sorted(flat))


def _step_blocked(a, b) -> bool:
    """No barrel step fits between lens element a and the next, b (templates.lens_element.LensElement,
    flat bevels included): the larger one's face between the two rims reaches past the smaller one's
    rim along the axis (the layout's test, cad.layout: edges overlapping axially)."""
    r = min(a.outer_radius, b.outer_radius)
    za = float(np.max(a.back_z(np.linspace(r, a.outer_radius, 50))))
    zb = float(np.min(b.front_z(np.linspace(r, b.outer_radius, 50))))
    return zb <= za


def _faces_meet(a, b, r_lo: float, r_hi: float) -> float | None:
    """Radius in [r_lo, r_hi] where face b (behind) comes to face a (in front), mm; None if they
    stay apart there. Below r_lo (the light and the contact margin) they must not meet. Only where
    both faces exist (a deep face ends at its reach: it is ground flat beyond, cad.lens_groups)."""
    rs = np.linspace(0.0, min(r_hi, a.profile.max_radius(), b.profile.max_radius()), 2001)
    gap = b.z(rs) - a.z(rs)
    closed = np.flatnonzero(gap <= 0.0)
    if not len(closed) or rs[closed[0]] < r_lo:
        return None
    j = closed[0]   # linear between the last open and the first closed sample
    return float(rs[j - 1] + (rs[j] - rs[j - 1]) * gap[j - 1] / (gap[j - 1] - gap[j]))


def _allowance(p: Prescription) -> float:
    """The edge allowance: mechanical minus clear semi-diameter, from the largest clear semi-diameter."""
    return _clamp(0.06 * max(float(s.clear_semi_diameter) for s in p.surfaces), 0.3, 2.0)


def _faces_curling_toward_the_stop(p: Prescription) -> tuple[int, ...]:
    """1-based numbers of the lens faces bounding the stop's air gap that curl toward the stop between
    their clear semi-diameter and the rim (a double Gauss's deep inner faces): candidates for a flat."""
    if p.has_mirrors:
        return ()
    stop, zv = p.stop_index, p.vertex_z
    out = []
    for g in p.lens_groups():
        for i, side in ((g[-1], +1), (g[0], -1)):
            between = range(min(i, stop) + 1, max(i, stop))
            if i == stop or (stop - i) * side < 0 or any(not p.surfaces[j].is_air_after for j in between):
                continue
            s = p.surfaces[i]
            c = float(s.clear_semi_diameter)
            r = min(c + _allowance(p), Profile.of(s).max_radius())
            sag = lambda h, s=s: float(Profile.of(s).sag(h * h))  # noqa: E731
            if (sag(r) - sag(c)) * side > 0:
                out.append(i + 1)
    return tuple(out)


def starter_mount(p: Prescription, name: str) -> tuple[dict, str | None]:
    """mount.toml as a dict of tables, every dimension derived from the lens (module docstring),
    and why no mount was found that builds (None when it builds).

    The starting seatings are spacers with widened edges, then shoulders and rings where a spacer
    cannot reach; if faces beside the stop curl toward it, both again with those faces ground flat
    from their clear semi-diameter (lens_edge.flat_faces: room for the diaphragm between deep inner
    faces). Each is checked as `regenerate` checks it (the layout planner, the profile checks, then
    the solids: cad.mount_search.refusal); the first that passes wins. When none does, the planner's
    alternatives are tried where its refusal points (cad.mount_search: seats, rims, flat faces,
    margins), and when none does, the seatings again with every rim enlarged together (`_wider_rims`,
    a search of its own). When nothing builds, the first seating is returned with the refusals met on
    the way.
    """
    gap = _faces_curling_toward_the_stop(p)
    base: dict[bool, dict] = {}   # each seating's mount.toml made once (0.5-1 s), when it is needed

    def starts():
        for flats in ((), gap) if gap else ((),):
            for widen in (True, False):
                if widen not in base:
                    base[widen] = _mount(p, name, widen)
                mount = copy.deepcopy(base[widen])
                edge = mount["lens_edge"]
                if flats:
                    edge["flat_faces"] = sorted(set(flats) | set(edge.get("flat_faces", ())))
                yield mount

    mount, refused = find_mount(p, starts())
    if mount is None:
        mount, _ = find_mount(p, _wider_rims(p, name, gap))
    return (mount, None) if mount is not None else (base[True], _why_not(refused) + "; nor with every rim "
            f"enlarged together, {', '.join(f'{m:.3g}' for m in rim_margins(p))} mm outside its clear aperture")


RIM_MARGINS = (1.0, 1.5, 2.0, 3.0)   # every rim's margin over its clear aperture, in edge allowances


def rim_margins(p: Prescription) -> tuple[float, ...]:
    """The margins of every rim over its element's clear aperture that init tries together, mm."""
    return tuple(round(f * _allowance(p), 3) for f in RIM_MARGINS)


def _wider_rims(p: Prescription, name: str, gap: tuple[int, ...]):
    """The starting seatings again with every rim enlarged together: each element's mechanical
    semi-diameter its clear one plus one margin for all (`rim_margins`, smallest first), the file's
    own rims set aside. Where rims sit too close to the clear aperture for the chamfer and the seat's
    contact (OpticStudio's automatic rim: the clear semi-diameter plus a small chip zone), widening one
    element moves the fault to the next: an engineer widens them all by the same margin."""
    for margin in rim_margins(p):
        for flats in ((), gap) if gap else ((),):
            for widen in (True, False):
                mount = _mount(p, name, widen, rim_margin=margin)
                if flats:
                    edge = mount["lens_edge"]
                    edge["flat_faces"] = sorted(set(flats) | set(edge.get("flat_faces", ())))
                yield mount


def _why_not(refused: list) -> str:
    """One paragraph: the first plan's refusal, then what the alternatives ran into, each reason once."""
    first = refused[0][1]
    reasons: dict[str, str] = {}
    for what, why in refused[1:]:
        if why.kind != first.kind:
            reasons.setdefault(why.kind, f"with {what}: {why.message.rstrip('.')}")
    tail = "; ".join(list(reasons.values())[:3]) if reasons else "each was refused for the same reason"
    return f"{first.paragraph.rstrip('.')}. {len(refused) - 1} alternatives the planner knows were tried " \
           f"(seats, rims, flat faces, margins), none builds: {tail}"


def _chamfer(p: Prescription) -> float:
    return _round(min(0.1, _allowance(p) / 8), 3)


def _min_thickness(p: Prescription) -> float:
    a = max(float(s.clear_semi_diameter) for s in p.surfaces)
    return _round(_clamp(0.04 * a, 0.2, MountSpec().checks.min_thickness_mm), 2)


def least_edge(p: Prescription) -> float:
    """The glass a starter mount needs at an element's edge, mm: its least thickness ([checks]
    min_thickness_mm) after two protective chamfers (lens_edge.chamfer_mm): the gap between an
    element's faces where the glass allows it to end (design.edges.clip_crossing_elements)."""
    return _min_thickness(p) + 2.0 * _chamfer(p)


def _mount(p: Prescription, name: str, widen: bool, rim_margin: float | None = None) -> dict:
    """The starter's mount.toml; `rim_margin`: every rim that far outside its element's clear aperture
    (the file's mechanical semi-diameters set aside), else the edge allowance where the file gives none."""
    a = max(float(s.clear_semi_diameter) for s in p.surfaces)
    allowance = _allowance(p)
    chamfer = _chamfer(p)
    wall = _round(_clamp(0.15 * a, 0.8, 4.0), 1)
    lip = _round(_clamp(0.1 * a, 0.5, 2.0), 1)
    field = p.max_field_deg
    margin = _round(_clamp(0.04 * a, 0.1, 1.0), 2)   # bores of spacers, vanes, housing above the beam
    exclusion = field + SUN_MARGIN_DEG
    a1 = float(p.surfaces[0].clear_semi_diameter)
    spread = math.tan(math.radians(exclusion)) - math.tan(math.radians(field))
    hood_length = _clamp(2 * a1 / spread, a1, MAX_HOOD_DIAMETERS * 2 * a1)
    if p.finite_object:  # the hood stays clear of the object: its mouth at most half way to the object plane
        hood_length = min(hood_length, 0.5 * p.object_distance)
    hood_length = _round(hood_length, 1)
    vane_room = _clamp(0.2 * a1, 0.8, 4.0)
    beam_at_mouth = Envelope(p, -hood_length - 10.0, 0.0, step=0.5).max_over(-hood_length - 10.0, 0.0)
    hood_radius = beam_at_mouth + margin + vane_room
    vanes = int(_clamp(round(hood_length / (2 * hood_radius)), 1, 4))
    width, height = detector_size(p)
    contact = _round(min(0.5, allowance / 4), 3)
    edge = {"style": "chamfered", "chamfer_mm": chamfer, "allowance_mm": _round(allowance, 3),
            "contact_margin_mm": contact}
    min_thickness = _min_thickness(p)
    retainer = _round(_clamp(0.05 * a, 0.3, 3.0), 1)
    # a lens with mirrors is laid out in cells (lensmount.cad.catadioptric): no seats or edges to choose,
    # and no hood or housing yet (the hood and housing tables keep the exclusion angle and the detector)
    rims = p if rim_margin is None else p.with_surfaces([replace(s, mechanical_semi_diameter=None)
                                                         for s in p.surfaces])
    semi, seat_of, flat = ({}, {}, ()) if p.has_mirrors else _edges_and_seats(
        rims, allowance if rim_margin is None else rim_margin, chamfer, contact, min_thickness, retainer, margin,
        widen)
    if rim_margin is not None and not p.has_mirrors:   # every rim written: the file's own would apply elsewhere
        edge["allowance_mm"] = _round(rim_margin, 3)
        first = 1
        for g in p.lens_groups():
            rim = _round(group_rim(rims, g, first, LensEdge(allowance_mm=rim_margin)), 3)
            for k in range(first, first + len(g) - 1):
                semi.setdefault(k, rim)
            first += len(g) - 1
    if semi:
        edge["semi_diameter_mm"] = {str(k): v for k, v in semi.items()}
    if flat:
        edge["flat_faces"] = list(flat)
    # An image formed in a medium (an immersion objective's water or oil) lies on the specimen, in contact
    # with the medium after the last face: no detector housing behind it, and the last element is bonded
    # into the barrel's nose (a shoulder or ring behind it would stand in the liquid, past the image).
    immersed = p.immersion_face is not None
    return {
        "name": f"{name} mount",
        "barrel": {"wall_mm": wall, "radial_clearance_mm": 0.03, "lip_mm": lip},
        "lens_edge": edge,
        "seats": {"front": "retainer", "rear": "bonded" if immersed else "shoulder", "default": "spacer"}
        | ({"element": {str(k): v for k, v in seat_of.items()}} if seat_of else {}),
        "spacers": {"aperture_margin_mm": margin},
        "retainer": {"thickness_mm": retainer},
        "diaphragm": {"thickness_mm": _round(_clamp(0.03 * a, 0.3, 1.0), 1), "land_mm": 0.05}
                      | ({"bevel_side": "front"} if _land_toward_front_stop_face(p) else {}),
        "vanes": {"placement": "even", "count": vanes, "aperture_margin_mm": margin, "edge_width_mm": 0.05,
                  "thickness_mm": _round(_clamp(0.05 * a, 0.3, 1.0), 1)},
        "hood": {"length_mm": hood_length, "inner_diameter_mm": _round(2 * hood_radius, 1),
                 "exclusion_deg": _round(exclusion, 2)} | ({"enabled": False} if p.has_mirrors else {}),
        "housing": ({"enabled": False} if p.has_mirrors or immersed else {}) | {
                    "detector_width_mm": width, "detector_height_mm": height,
                    "detector_clearance_mm": _round(_clamp(0.1 * max(width, height), 0.3, 2.0), 1),
                    "back_gap_mm": _round(_clamp(0.1 * a, 1.0, 5.0), 1), "wall_mm": wall},
        "checks": {"min_thickness_mm": min_thickness},
        "tessellation": {"linear_tolerance_mm": _round(_clamp(0.002 * a, 0.005, 0.05), 3),
                         "angular_tolerance_deg": 6.0},
    }


def _land_toward_front_stop_face(p: Prescription) -> bool:
    """The stop is a lens's front face and the lens has off-axis fields: the diaphragm stands in front of the
    glass, and its land (the stop) goes on the plate's rear face, a clearance from the glass, not the plate's
    thickness away: there the field beams, which cross the axis at the face, run off-centre by that distance
    times tan(field), and the land, passing the designed pupil, would clip them (OptoSigma objective: 0.4 mm x
    tan 3.43 deg = 24 um on a 4 mm pupil radius). The bevel then faces the light."""
    i = p.stop_index
    return (not p.has_mirrors and not p.object_telecentric and any(p.field_values) and p.holds_glass_after(i)
            and p.material_before(i).upper() == "AIR")


def starter_finishes(p: Prescription) -> dict:
    """The design's finishes.toml for this lens: the seed paper's case 2 (every mount face and lens
    edge Lambertian 5 %, the diaphragm edge absorbing) with every mirror's coated face scattering as a
    polished mirror (`POLISHED_MIRROR`, `[assign] "surface:N"`: in a Cassegrain the primary's scatter
    of a sun outside the field is a main stray path; with black cells and baffles, often the main one)."""
    mirrors = p.mirror_surfaces
    # a catadioptric mount has no diaphragm: the mirrors' coated zones are the stop
    edge = {} if p.has_mirrors else {"role:diaphragm-edge": "absorber"}
    return {
        "finishes": {"lambert-5": {"model": "lambertian", "reflectance": 0.05}}
                    | ({"polished-mirror": dict(POLISHED_MIRROR)} if mirrors else {}),
        "coatings": {"default": "perfect-ar"},
        "assign": {"*": "lambert-5"} | edge | {surface_rule(i): "polished-mirror" for i in mirrors},
    }


def case2_scene(p: Prescription, mount: dict, name: str) -> dict:
    """The seed paper's case 2 for this lens (the test condition): a bright source at the hood's exclusion
    angle. At infinity the sun; for a finite object a point on the object plane, as far off the axis as
    that angle reaches (`optics.paraxial.object_height_at`): the light a finite-conjugate lens meets from outside its field."""
    angle = mount["hood"]["exclusion_deg"]
    width, height = mount["housing"]["detector_width_mm"], mount["housing"]["detector_height_mm"]
    nx = 360
    ny = max(1, int(round(nx * height / width)))
    if p.finite_object:
        h = object_height_at(p, angle)
        source = {"type": "point", "height_mm": _round(h, 3), "azimuth_deg": 90.0}
        said = f"a point on the object plane {h:.4g} mm off the axis, {SUN_MARGIN_DEG:g}° outside the field"
    else:
        source = {"type": "sun", "off_axis_deg": angle, "azimuth_deg": 90.0, "angular_diameter_deg": 0.53,
                  "limb_darkening": False}
        said = f"the sun at {angle:g}° ({SUN_MARGIN_DEG:g}° outside the field)"
    return {
        "description": f"The seed paper's case 2 on {name}: {said}, with the design's finishes (finishes.toml)",
        "source": source,
        "detector": {"width_mm": width, "height_mm": height, "pixels": [nx, ny]},
        "effects": {"scatter": True, "ghosts": False, "direct": False, "absorption": True},
        "run": {"photons": 200_000, "passes": 32, "seed": 1, "target_rel_error": 0.05, "time_s": 120},
    }


# A polished mirror's micro-roughness: ABg g = 2 with its knee at 0.57° (B = 1e-4) and TIS = πA ln(1 + 1/B)
# = 2.1e-3 = (4πσ/λ)² for σ = 2 nm rms at 550 nm. A starting point: measured data replace it (fit-abg).
POLISHED_MIRROR = {"model": "abg", "A": 7.2e-5, "B": 1e-4, "g": 2.0}


def object_scene(p: Prescription, case2: dict, name: str) -> dict | None:
    """For a lens with a finite object: the object itself as the source, a Lambertian disc on the
    object plane filling the field (a point on the axis when the field is one point), with the
    direct image on and the mount as in case 2: the veiling glare the mount adds to the object's
    own image. None for an object at infinity."""
    if not p.finite_object:
        return None
    field = max((abs(h) for h in p.object_heights_mm), default=0.0)
    source = {"type": "disc", "radius_mm": _round(field, 3)} if field > 0.0 else {"type": "point"}
    return case2 | {
        "description": f"The object of {name} as the source: " + (f"a Lambertian disc of {field:g} mm radius"
                       if field > 0.0 else "a point on the axis") + f" on the object plane "
                       f"{p.object_distance:g} mm in front, with the design's finishes",
        "source": source,
        "effects": case2["effects"] | {"direct": True},
    }


__all__ = ["starter_mount", "least_edge", "rim_margins", "starter_finishes", "case2_scene", "POLISHED_MIRROR",
           "object_scene", "detector_size"]
