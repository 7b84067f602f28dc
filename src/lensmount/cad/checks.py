"""Interference and sanity checks before export, on the parts' (r, z) profiles.

Every built-in part is a solid of revolution, so two parts overlap exactly when
their profiles overlap in the half plane; the overlap depth (how far one profile
reaches into the other) is the number the error reports. Checks:

* any two parts: no overlap deeper than OVERLAP_TOL_MM (contacts touch, never cut);
* spacers, retainers and shoulders touch lenses outside the clear aperture;
* no mechanical face enters the beam footprint (real rays, full field); for the
  diaphragm, whose land *is* the stop, the beam its land passes (`apertures.beam_through_land`);
* lens edge to bore clearance at least `checks.min_radial_clearance_mm`;
* plates and walls at least `checks.min_thickness_mm` (knife-edge lands excepted);
* glass and metal either touch at a designed contact, the metal leaving the glass
  at the contact wedge (`seats.wedge_deg`), or stay `seats.clearance_mm` apart: no
  sub-micrometre sliver a ray leaving the glass could slip through.

A violation raises GeometryError naming both parts and the overlap in mm.
"""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path as MplPath

from lensmount.cad.plan import Layout
from lensmount.design.mount import MountSpec
from lensmount.errors import GeometryError
from lensmount.templates.profile import outline

OVERLAP_TOL_MM = 2e-3
BEAM_TOL_MM = 1e-3
_SAMPLE_STEP_MM = 0.25
_NEAR_MM = 0.3  # points this close to the interpolated envelope get the exact test


def _densify(poly: np.ndarray, step: float = _SAMPLE_STEP_MM) -> np.ndarray:
    if not np.isfinite(poly).all():   # check_outlines names the part; this guards the other callers
        raise GeometryError("a part's profile has points at infinity", field="mount",
                            valid="parts whose every face exists where the profile follows it")
    out = []
    closed = np.vstack([poly, poly[:1]])
    for a, b in zip(closed[:-1], closed[1:]):
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        t = np.arange(n)[:, None] / n
        out.append(a + t * (b - a))
    return np.concatenate(out)


def _distance_to_boundary(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    a = poly
    b = np.roll(poly, -1, axis=0)
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip((ap * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300)[None], 0.0, 1.0)
    q = a[None] + t[..., None] * ab[None]
    return np.sqrt(((points[:, None, :] - q) ** 2).sum(-1)).min(axis=1)


def penetration(poly_a: np.ndarray, poly_b: np.ndarray) -> float:
    """How deep (mm) the boundary of either profile reaches into the other one."""
    depth = 0.0
    for p, q in ((poly_a, poly_b), (poly_b, poly_a)):
        lo, hi = q.min(0) - 1e-9, q.max(0) + 1e-9
        pts = _densify(p)
        pts = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
        if not len(pts):
            continue
        inside = MplPath(q).contains_points(pts)
        if inside.any():
            depth = max(depth, float(_distance_to_boundary(pts[inside], q).max()))
    return depth


def check_interference(outlines: dict[str, np.ndarray]) -> None:
    """Raise GeometryError for the deepest overlap between two parts."""
    names = list(outlines)
    boxes = {n: (o.min(0), o.max(0)) for n, o in outlines.items()}
    worst = (0.0, None, None)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            (la, ha), (lb, hb) = boxes[a], boxes[b]
            if np.any(la > hb + OVERLAP_TOL_MM) or np.any(lb > ha + OVERLAP_TOL_MM):
                continue
            d = penetration(outlines[a], outlines[b])
            if d > worst[0]:
                worst = (d, a, b)
    if worst[0] > OVERLAP_TOL_MM:
        d, a, b = worst
        raise GeometryError(f"{a} and {b} overlap by {d:.3f} mm", field="mount",
                            valid="parameters that leave the parts apart (larger gaps, smaller margins)")


def check_beam(layout: Layout, outlines: dict[str, np.ndarray]) -> None:
    """No mechanical part's profile reaches into the beam envelope (the diaphragm: the beam its land passes)."""
    if layout.beam is not None:  # a folded path: the rays themselves, past the central obscuration
        layout.beam.check(layout, outlines)
        return
    env = layout.envelope
    z_lo, z_hi = env.z[0], env.z[-1]
    for plan in layout.parts:
        if plan.kind == "lens" or plan.name not in outlines:
            continue
        pts = _densify(outlines[plan.name])
        pts = pts[(pts[:, 1] >= z_lo) & (pts[:, 1] <= z_hi)]
        # the diaphragm's land *is* the stop: the rays it stops are its to stop (a land off a curved
        # stop face stops a sliver of an off-axis beam aimed at the face); what it passes must clear it
        land = plan.template.land_range() if plan.kind == "diaphragm" else None
        if not len(pts):
            continue
        near = pts[:, 0] < env.at(pts[:, 1]) + _NEAR_MM
        if not near.any():
            continue
        pts = pts[near]
        into = env.exact(pts[:, 1], land) - pts[:, 0]  # the real rays at these very planes
        k = int(np.argmax(into))
        if into[k] > BEAM_TOL_MM:
            raise GeometryError(
                f"{plan.name} enters the beam footprint of the full field by {into[k]:.3f} mm at z = "
                f"{pts[k, 1]:.2f} mm (part radius {pts[k, 0]:.3f} mm, beam radius {pts[k, 0] + into[k]:.3f} mm)",
                field=f"{plan.kind}", valid="larger bores or aperture margins for this part")


def check_contacts(layout: Layout) -> None:
    for c in layout.contacts:
        if c.height < c.clear - 1e-9:
            raise GeometryError(
                f"{c.part} cuts into the clear aperture of {c.lens} (surface {c.surface + 1}) by "
                f"{c.clear - c.height:.3f} mm", field="lens_edge.contact_margin_mm",
                valid="a contact height at or above the clear semi-diameter")


def check_clearance(layout: Layout, spec: MountSpec) -> None:
    c = spec.barrel.radial_clearance_mm
    if c < spec.checks.min_radial_clearance_mm:
        lens = next(p.name for p in layout.parts if p.kind == "lens")
        raise GeometryError(
            f"{lens} and barrel: radial clearance {c} mm is below the minimum "
            f"{spec.checks.min_radial_clearance_mm} mm", field="barrel.radial_clearance_mm",
            valid=f"a clearance >= {spec.checks.min_radial_clearance_mm} mm")


def check_thickness(layout: Layout, spec: MountSpec) -> None:
    """Every part at least `checks.min_thickness_mm` thick where it is not a knife edge.

    Lenses, spacers, shoulders and rings are checked where they are planned
    (lensmount.cad.layout); here the plates and walls whose size comes straight
    from mount.toml.
    """
    min_t = spec.checks.min_thickness_mm
    for plan in layout.parts:
        t = plan.template
        sizes = {
            "diaphragm": lambda: ("plate thickness", t.thickness),
            "vane": lambda: ("thickness", t.thickness),
            "hood": lambda: ("wall", t.outer_radius - t.inner_radius),
            "housing": lambda: ("wall", t.wall),
            "retainer": lambda: ("thickness", t.thickness),
            "barrel": lambda: ("wall", t.outer_radius - max(r for r, _ in t.bore)),
            "baffle": lambda: ("wall", t.outer_radius - max(r for r, _ in t.bore)),
        }
        if plan.kind not in sizes:
            continue
        what, value = sizes[plan.kind]()
        if value < min_t:
            raise GeometryError(f"{plan.name}: {what} {value:.3f} mm is below the minimum {min_t} mm",
                                field=f"{plan.kind}", valid=f"a {what} >= {min_t} mm (checks.min_thickness_mm)")


GLASS_STEP_MM = 0.005  # spacing of the glass boundary samples for the gap measurement


def _glass_points(segments) -> np.ndarray:
    """(m, 2) points on a lens's profile, about GLASS_STEP_MM apart (exactly on arcs and lines)."""
    out = []
    for s in segments:
        ends = np.asarray(s.points, dtype=np.float64)
        length = float(np.hypot(*(ends[-1] - ends[0])))
        if s.kind == "arc":
            length *= 1.6  # an arc is longer than its chord; over-sampling is harmless
        n = int(min(200_000, max(2, np.ceil(length / GLASS_STEP_MM))))
        if s.kind == "line":
            t = np.linspace(0.0, 1.0, n)[:, None]
            out.append(ends[0] + t * (ends[-1] - ends[0]))
        else:
            out.append(s.polyline(n))
    return np.concatenate(out)


def glass_gaps(layout: Layout, spec: MountSpec, segments: dict[str, list]) -> list[tuple]:
    """Glass-to-metal gaps narrower than `seats.clearance_mm`, in the (r, z) profiles.

    Returns (lens, part, r, z, gap mm, distance mm from the nearest designed contact of
    that lens and part, or inf) for every sampled glass point whose distance to the part's
    profile is below the clearance. A designed contact shows as gaps that grow from 0 with
    the distance from it; anything else is a sliver.
    """
    c = spec.seats.clearance_mm
    lenses = [p for p in layout.parts if p.kind == "lens" and p.name in segments]
    metal = {p.name: outline(segments[p.name]) for p in layout.parts
             if p.kind != "lens" and p.name in segments}
    found = []
    for lens in lenses:
        pts = _glass_points(segments[lens.name])
        t = lens.template
        for name, poly in metal.items():
            lo, hi = poly.min(0) - c, poly.max(0) + c
            near = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
            if not len(near):
                continue
            gap = np.full(len(near), np.inf)
            for k in range(0, len(near), 4096):
                gap[k:k + 4096] = _distance_to_boundary(near[k:k + 4096], poly)
            thin = gap < c
            if not thin.any():
                continue
            touch = np.array([(ct.height, float((t.front_z if ct.surface == t.front.index else t.back_z)(ct.height)))
                              for ct in layout.contacts if ct.part == name and ct.lens == lens.name]).reshape(-1, 2)
            q = near[thin]
            dist = (np.sqrt(((q[:, None, :] - touch[None]) ** 2).sum(-1)).min(axis=1)
                    if len(touch) else np.full(len(q), np.inf))
            found += [(lens.name, name, float(r), float(z), float(g), float(s))
                      for (r, z), g, s in zip(q, gap[thin], dist)]
    return found


def slivers(layout: Layout, spec: MountSpec, segments: dict[str, list]) -> list[tuple]:
    """The gaps of `glass_gaps` that are neither the clearance (at least half of it: the
    clearance is set along the axis, and perpendicular to a 45° chamfer that leaves 71 %)
    nor a contact wedge (at least half the designed wedge opening at their distance from
    the contact; the contact point itself, gap 0, is fine). Tangent contacts open
    quadratically by design and are not judged."""
    if spec.seats.contact == "tangent":
        return []
    wedge, c = np.tan(np.radians(spec.seats.wedge_deg)), spec.seats.clearance_mm
    return [g for g in glass_gaps(layout, spec, segments) if g[4] < min(0.5 * c, 0.5 * wedge * g[5] - 1e-9)]


def check_glass_clearance(layout: Layout, spec: MountSpec, segments: dict[str, list]) -> None:
    bad = slivers(layout, spec, segments)
    if bad:
        lens, part, r, z, gap, _ = min(bad, key=lambda g: g[4])
        raise GeometryError(
            f"{part} runs {gap * 1e3:.2f} µm from the glass of {lens} at r = {r:.3f} mm, z = {z:.3f} mm "
            "without holding it: a sliver a ray leaving the glass can slip through",
            field="seats.clearance_mm", valid="parameters that let the part touch the glass at its contact "
            f"or stay at least {spec.seats.clearance_mm} mm away")


def check_outlines(layout: Layout, outlines: dict[str, np.ndarray]) -> None:
    """Every profile point finite: a face followed beyond where it exists (a sphere past its radius)
    gives points at infinity, and no check below can measure them."""
    for plan in layout.parts:
        poly = outlines.get(plan.name)
        if poly is not None and not np.isfinite(poly).all():
            r = poly[~np.isfinite(poly).all(axis=1)][0]
            raise GeometryError(f"{plan.name}: its profile leaves the plane at ({r[0]:g}, {r[1]:g}) mm (r, z): "
                                "a face followed beyond where it exists", field=plan.kind,
                                valid="dimensions that keep each face within its radius of curvature")


def check_layout(layout: Layout, spec: MountSpec, segments: dict[str, list]) -> None:
    """All checks, on the built-in profiles (`segments` per part name)."""
    outlines = {name: outline(segs) for name, segs in segments.items()}
    check_outlines(layout, outlines)
    check_contacts(layout)
    check_clearance(layout, spec)
    check_thickness(layout, spec)
    check_interference(outlines)
    check_glass_clearance(layout, spec, segments)
    check_beam(layout, outlines)


__all__ = ["check_layout", "check_thickness", "penetration", "glass_gaps", "slivers", "OVERLAP_TOL_MM"]
