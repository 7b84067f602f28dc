"""Solids of revolution from a tagged 2D profile: the base of every built-in template.

A part is drawn as a closed profile in the (r, z) half plane (r >= 0): a list of
`Segment`s, each carrying the role its revolved face will have (`optical` with
its surface index, `lens-edge`, `bevel`, `mount`, ...). Revolving about the
optical axis turns every segment off the axis into exactly one CAD face, so a face
is tagged by finding the segment its points lie on. The same lookup tags the faces
of user-template parts that follow the built-in profile, and `mount` otherwise.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Protocol

import numpy as np
from scipy.interpolate import CubicSpline

_AXIS_TOL = 1e-9  # mm; segments with both ends this close to the axis are the axis itself
_MATCH_TOL = 1e-3  # mm; a face point farther than this from every segment is `mount`
_ARC_SAGITTA = 1e-5  # mm; an arc's polyline stays this close to it (a hundredth of the match tolerance)


@dataclass(frozen=True)
class Segment:
    """One piece of a part's (r, z) profile.

    Args:
        kind: `line`, `arc` (3 points: start, any point on the arc, end) or `spline`.
        points: (k, 2) (r, z) points, mm; first and last are the segment's ends.
        role: face role after revolving (lensmount.mesh.ROLES).
        surface: 0-based prescription surface index for optical faces, else -1.
    """

    kind: str
    points: tuple[tuple[float, float], ...]
    role: str = "mount"
    surface: int = -1

    @property
    def start(self):
        return self.points[0]

    @property
    def end(self):
        return self.points[-1]

    def on_axis(self) -> bool:
        return all(abs(p[0]) <= _AXIS_TOL for p in self.points)

    def polyline(self, n: int = 64) -> np.ndarray:
        """(m, 2) points along the segment for distance queries."""
        pts = np.asarray(self.points, dtype=np.float64)
        if self.kind == "line":
            return pts[[0, -1]]
        if self.kind == "arc":
            return _arc_points(pts[0], pts[1], pts[2], n)
        return pts  # spline: its defining points are dense (sag samples)


def outline(segments) -> np.ndarray:
    """Closed (m, 2) polyline of a profile: arcs and splines sampled densely."""
    pts = []
    for s in segments:
        pl = s.polyline(256)
        pts.append(pl[:-1])
    return np.concatenate(pts)


def _arc(a, b, c):
    """The circle through a, b, c and the arc from a to c through b: (centre (2,), radius, start angle,
    signed sweep), or None when the three points are collinear."""
    ax, ay = a
    bx, by = b
    cx, cy = c
    d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    if abs(d) < 1e-14:
        return None
    ux = ((ax * ax + ay * ay) * (by - cy) + (bx * bx + by * by) * (cy - ay) + (cx * cx + cy * cy) * (ay - by)) / d
    uy = ((ax * ax + ay * ay) * (cx - bx) + (bx * bx + by * by) * (ax - cx) + (cx * cx + cy * cy) * (bx - ax)) / d
    ta, tb, tc = (np.arctan2(p[1] - uy, p[0] - ux) for p in (a, b, c))
    # go from ta to tc through tb
    def ccw(t0, t1):
        return (t1 - t0) % (2 * np.pi)
    sweep = ccw(ta, tc) if ccw(ta, tb) <= ccw(ta, tc) else -ccw(tc, ta)
    return np.array([ux, uy]), float(np.hypot(ax - ux, ay - uy)), ta, sweep


def _arc_points(a, b, c, n):
    """Points on the circle through a, b, c from a to c (through b)."""
    arc = _arc(a, b, c)
    if arc is None:
        return np.array([a, c])
    centre, rad, ta, sweep = arc
    ts = ta + np.linspace(0.0, sweep, n)
    return np.stack([centre[0] + rad * np.cos(ts), centre[1] + rad * np.sin(ts)], axis=1)


def polygon(points, roles=None) -> list[Segment]:
    """Closed polygon of line segments through (r, z) points; roles[i] for edge i → i+1.

    Repeated points and collinear middle points are dropped (they would make
    zero-length or split faces). Roles default to `mount`.
    """
    pts = [tuple(map(float, p)) for p in points]
    roles = list(roles) if roles is not None else ["mount"] * len(pts)
    # drop repeated points (role of the dropped edge goes with it)
    keep_p, keep_r = [], []
    for i, p in enumerate(pts):
        q = pts[(i + 1) % len(pts)]
        if np.hypot(p[0] - q[0], p[1] - q[1]) > 1e-9:
            keep_p.append(p)
            keep_r.append(roles[i])
    pts, roles = keep_p, keep_r
    # drop collinear middle points when both edges share a role
    changed = True
    while changed and len(pts) > 3:
        changed = False
        for i in range(len(pts)):
            a, b, c = pts[i - 1], pts[i], pts[(i + 1) % len(pts)]
            cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
            if abs(cross) < 1e-12 and roles[i - 1] == roles[i]:
                del pts[i]
                del roles[i]
                changed = True
                break
    return [Segment("line", (pts[i], pts[(i + 1) % len(pts)]), roles[i]) for i in range(len(pts))]


def revolve(segments: list[Segment]):
    """A build123d Solid: the closed profile revolved 360° about the z axis."""
    # lazy: build123d/OCP take seconds to load; planning a layout does without them
    from build123d import Axis, Edge, Face, Solid, Wire

    edges = []
    for s in segments:
        p = [(float(r), 0.0, float(z)) for r, z in s.points]
        if s.kind == "line":
            edges.append(Edge.make_line(p[0], p[-1]))
        elif s.kind == "arc":
            edges.append(Edge.make_three_point_arc(p[0], p[1], p[2]))
        else:
            edges.append(Edge.make_spline(p))
    face = Face(Wire(edges))
    return Solid.revolve(face, 360.0, Axis.Z)


def face_roles(solid, segments: list[Segment]) -> list[tuple[str, int]]:
    """(role, surface) for every face of `solid`, in `solid.faces()` order.

    A point in the middle of each face's parameter range is mapped to (r, z) and
    matched to the nearest profile segment off the axis.
    """
    lines = [(s, _as_built(s)) for s in segments if not s.on_axis()]
    out = []
    for f in solid.faces():
        rz = _profile_point(f)
        best, best_d = None, np.inf
        for s, pl in lines:
            d = _distance_to_polyline(rz, pl)
            if d < best_d:
                best, best_d = s, d
        if best is None or best_d > _MATCH_TOL * max(1.0, abs(rz).max() * 1e-3):
            out.append(("mount", -1))
        else:
            out.append((best.role, best.surface))
    return out


def unmatched_segments(roles: list[tuple[str, int]], segments: list[Segment]) -> list[Segment]:
    """The profile's segments off the axis that no face of `roles` (face_roles of the revolved profile)
    was tagged with: none for a built-in template, whose every such segment is one CAD face."""
    left = [(r, s) for r, s in roles]
    out = []
    for seg in segments:
        if seg.on_axis():
            continue
        if (seg.role, seg.surface) in left:
            left.remove((seg.role, seg.surface))
        else:
            out.append(seg)
    return out


def _profile_point(face) -> np.ndarray:
    """(r, z) of a point inside a revolved face: the middle of its parameter range, or on a plane (a
    revolved annulus, whose parameter box is centred on the axis, off the face) halfway between its rims."""
    # lazy: build123d/OCP take seconds to load; a solid was built with them already
    from build123d import GeomType

    if face.geom_type != GeomType.PLANE:
        p = face.position_at(0.5, 0.5)
        return np.array([np.hypot(p.X, p.Y), p.Z])
    rims = [np.hypot(v.X, v.Y) for v in face.vertices()]
    inner = min(rims) if max(rims) - min(rims) > _AXIS_TOL else 0.0   # one rim: a disc on the axis
    return np.array([0.5 * (inner + max(rims)), face.vertices()[0].Z])


def _as_built(s: Segment) -> np.ndarray:
    """The segment's polyline, a spline's refined along the cubic the solid interpolates through its points
    (chord-length parameters, as `Edge.make_spline`): between a steep asphere's sag samples the face
    bows farther from their chords than the match tolerance (the 20 mm deep face of Thorlabs'
    ASL5040-UV by 5.6e-3 mm, which made it `mount`)."""
    if s.kind == "arc":
        return s.polyline(_arc_samples(*s.points, sagitta=_ARC_SAGITTA))
    pl = s.polyline()
    if s.kind != "spline":
        return pl
    keep = np.concatenate([[True], np.hypot(*np.diff(pl, axis=0).T) > 0.0])
    pl = pl[keep]
    if len(pl) < 4:
        return pl
    t = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pl, axis=0).T))])
    return CubicSpline(t, pl, axis=0)(np.linspace(0.0, t[-1], 8 * (len(pl) - 1) + 1))


def _arc_samples(a, b, c, sagitta: float) -> int:
    """Points along the arc a-b-c whose chords stay within `sagitta` of it (a chord of angle δ on a circle
    of radius R bows R δ²/8 off it): a 64-point deep face (R 85 mm over 49°) bows 2e-3 mm, twice the tolerance."""
    arc = _arc(a, b, c)
    if arc is None:
        return 2
    _, rad, _, sweep = arc
    return max(64, int(np.ceil(abs(sweep) / np.sqrt(8.0 * sagitta / rad))) + 1)


def _distance_to_polyline(p, pl):
    a, b = pl[:-1], pl[1:]
    ab = b - a
    t = np.clip(((p - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-300), 0.0, 1.0)
    q = a + t[:, None] * ab
    return float(np.sqrt(((q - p) ** 2).sum(1)).min())


class Template(Protocol):
    """What every part template offers the CAD layer: its tagged (r, z) profile, its solid (a
    build123d Solid, placed in the assembly frame) and its parameters (hashing, user templates).
    A new kind of part: a dataclass in its own module of this folder deriving from `RevolvedPart`
    (docs/architecture.md, "Where to add a template")."""

    def segments(self) -> list[Segment]: ...

    def build(self): ...

    def params(self) -> dict: ...


@dataclass
class RevolvedPart:
    """Base of the built-in templates: subclasses give `segments()`; placement is in the profile."""

    def segments(self) -> list[Segment]:  # pragma: no cover - abstract
        raise NotImplementedError

    def build(self):
        """The part as a build123d Solid."""
        return revolve(self.segments())

    def params(self) -> dict:
        """The template's parameters (for hashing and for user templates)."""
        return asdict(self)


__all__ = ["Segment", "outline", "polygon", "revolve", "face_roles", "unmatched_segments", "Template", "RevolvedPart"]
