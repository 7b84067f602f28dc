"""Lens element: a solid of revolution bounded by its two optical faces, the ground
cylindrical edge and (optionally) protective chamfers of size b: from the surface at
radius R - b straight to the edge cylinder, b inside the surface's own edge height
(45° on a flat face).

Spherical faces are exact arcs (so the STEP face is a true sphere), planes are
lines, conics, aspheres and Q-type faces a spline through sag samples. Cemented interfaces get
no chamfer: both elements of a cemented group end on the same radius there.
A flat bevel (`front_flat_from`, `back_flat_from`) turns a face into a flat annulus from
that radius out (at the face's z there): a meniscus whose faces close in toward the rim
keeps a thick edge, and the seat rests on the flat. A ground annulus (`front_ground_from`,
`back_ground_from`) keeps the face's curve but not its polish (role `bevel`): a cemented
face left bare outside a smaller (stepped) partner, which the light of its interface never reaches.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from lensmount.optics.profiles import Profile
from lensmount.optics.qtype import QType
from lensmount.templates.profile import RevolvedPart, Segment

_SPLINE_POINTS = 41


@dataclass(frozen=True)
class OpticalFace:
    """One optical surface placed on the axis.

    Args:
        index: 0-based prescription surface index.
        z_vertex: vertex z, mm (assembly frame).
        curvature: 1/mm. conic: k. aspheric: (A4, A6, ...). qtype: a Forbes Q-type departure or None.
    """

    index: int
    z_vertex: float
    curvature: float = 0.0
    conic: float = 0.0
    aspheric: tuple[float, ...] = ()
    qtype: QType | None = None

    @classmethod
    def of(cls, index: int, z_vertex: float, surface) -> "OpticalFace":
        """The face of prescription surface `surface` (index `index`) with its vertex at z_vertex."""
        return cls(index, z_vertex, surface.curvature, surface.conic, tuple(surface.aspheric), surface.qtype)

    @property
    def profile(self) -> Profile:
        return Profile(self.curvature, self.conic, tuple(self.aspheric), self.qtype)

    def z(self, r) -> np.ndarray:
        """z of the surface at radius r (array), mm."""
        r = np.asarray(r, dtype=np.float64)
        return self.z_vertex + self.profile.sag(r * r)

    def segment(self, r_end: float, reverse: bool = False) -> Segment:
        """The face's profile from the axis to r_end (or back when reverse)."""
        piece = face_piece(self, 0.0, r_end)
        return replace(piece, points=piece.points[::-1]) if reverse else piece


def face_piece(face: OpticalFace, r0: float, r1: float, role: str = "optical") -> Segment:
    """The face's profile from radius r0 to r1 (either order): a line, an exact arc or a spline."""
    prof = face.profile
    surface = face.index if role == "optical" else -1
    if prof.is_plane or (abs(face.curvature) < 1e-9 and prof.is_conic):
        pts = [(r0, float(face.z(r0))), (r1, float(face.z(r1)))]
        return Segment("line", tuple(pts), role, surface)
    if face.conic == 0.0 and prof.is_conic:
        rm = 0.5 * (r0 + r1)
        pts = [(r0, float(face.z(r0))), (rm, float(face.z(rm))), (r1, float(face.z(r1)))]
        return Segment("arc", tuple(pts), role, surface)
    rs = np.linspace(r0, r1, _SPLINE_POINTS)
    return Segment("spline", tuple(zip(rs.tolist(), face.z(rs).tolist())), role, surface)


@dataclass
class LensElement(RevolvedPart):
    """A lens element.

    Args:
        front: object-side optical face.
        back: image-side optical face.
        outer_radius: mechanical semi-diameter (radius of the ground edge), mm.
        front_chamfer: chamfer size at the front edge, mm (0 = sharp; 0 at cemented faces).
        back_chamfer: chamfer size at the back edge, mm.
    """

    front: OpticalFace
    back: OpticalFace
    outer_radius: float
    front_chamfer: float = 0.0
    back_chamfer: float = 0.0
    front_flat_from: float | None = None   # flat bevel: the front face is flat from this radius out
    back_flat_from: float | None = None
    front_ground_from: float | None = None   # the face ground (not polished) on its own curve from here
    back_ground_from: float | None = None    # out: a cemented face left bare outside a stepped partner

    def face_z(self, front: bool, r) -> np.ndarray:
        """The optical face's z, held at its value at the flat bevel's radius beyond it."""
        face, flat = (self.front, self.front_flat_from) if front else (self.back, self.back_flat_from)
        r = np.asarray(r, dtype=np.float64)
        return face.z(r if flat is None else np.minimum(r, flat))

    def edge_z(self) -> tuple[float, float]:
        """z range of the ground cylindrical edge (front end, back end)."""
        R = self.outer_radius
        return (float(self.face_z(True, R)) + self.front_chamfer, float(self.face_z(False, R)) - self.back_chamfer)

    def front_z(self, r) -> np.ndarray:
        """z of the glass's object-side boundary at radius r <= outer_radius (chamfer included)."""
        r = np.asarray(r, dtype=np.float64)
        R, b = self.outer_radius, self.front_chamfer
        z = self.face_z(True, np.minimum(r, R - b))
        if b > 0:  # the chamfer: straight from (R - b, surface) to (R, edge start)
            z0, z1 = float(self.face_z(True, R - b)), self.edge_z()[0]
            z = np.where(r > R - b, z0 + (z1 - z0) * (r - (R - b)) / b, z)
        return z

    def back_z(self, r) -> np.ndarray:
        """z of the glass's image-side boundary at radius r <= outer_radius."""
        r = np.asarray(r, dtype=np.float64)
        R, b = self.outer_radius, self.back_chamfer
        z = self.face_z(False, np.minimum(r, R - b))
        if b > 0:
            z0, z1 = float(self.face_z(False, R - b)), self.edge_z()[1]
            z = np.where(r > R - b, z0 + (z1 - z0) * (r - (R - b)) / b, z)
        return z

    def center_thickness(self) -> float:
        return self.back.z_vertex - self.front.z_vertex

    def edge_thickness(self) -> float:
        a, b = self.edge_z()
        return b - a

    def segments(self) -> list[Segment]:
        R, bf, bb = self.outer_radius, self.front_chamfer, self.back_chamfer
        ff = R - bf if self.front_flat_from is None else min(self.front_flat_from, R - bf)
        fb = R - bb if self.back_flat_from is None else min(self.back_flat_from, R - bb)
        gf = self.front_ground_from
        segs = [self.front.segment(ff)] if gf is None or gf >= ff else [self.front.segment(gf),
                                                                         face_piece(self.front, gf, ff, "bevel")]
        if ff < R - bf:   # the flat bevel, ground like the chamfer
            segs.append(Segment("line", (segs[-1].end, (R - bf, segs[-1].end[1])), "bevel"))
        zf_edge, zb_edge = self.edge_z()
        p = segs[-1].end
        if bf > 0:
            segs.append(Segment("line", (p, (R, zf_edge)), "bevel"))
        segs.append(Segment("line", ((R, zf_edge), (R, zb_edge)), "lens-edge"))
        gb = self.back_ground_from
        ground = gb is not None and gb < fb
        back = self.back.segment(gb if ground else fb, reverse=True)
        z_fb = float(self.face_z(False, fb))
        flat_b = (R - bb, z_fb)
        if bb > 0:
            segs.append(Segment("line", ((R, zb_edge), flat_b), "bevel"))
        if fb < R - bb:
            segs.append(Segment("line", (flat_b, (fb, z_fb)), "bevel"))
        if ground:
            segs.append(face_piece(self.back, fb, gb, "bevel"))
        segs.append(back)
        segs.append(Segment("line", (back.end, segs[0].start), "mount"))  # on the axis: no face
        return segs

    def params(self) -> dict:
        d = super().params()
        for side in ("front", "back"):
            face_params(d[side])
        return d


def face_params(d: dict) -> None:
    """An `OpticalFace`'s asdict in place as plain lists; no `qtype` key on a face without one (the
    parameters, and the parts cached under them, of every other face stay as they were)."""
    d["aspheric"] = list(d["aspheric"])
    if d["qtype"] is None:
        del d["qtype"]
    else:
        d["qtype"]["coefficients"] = list(d["qtype"]["coefficients"])


@dataclass(frozen=True)
class GroupOutline:
    """What a cemented group shows its seats when one outer element is edged smaller than its
    partner (a stepped group): at each radius the glass's object-side boundary is that of the first
    element reaching that far, the image-side boundary that of the last. A seat touching the outline
    outside the small element touches the partner's cemented face there."""

    elements: tuple[LensElement, ...]

    @property
    def outer_radius(self) -> float:
        return max(el.outer_radius for el in self.elements)

    @property
    def _widest(self) -> LensElement:
        return max(self.elements, key=lambda el: el.outer_radius)

    @property
    def front_chamfer(self) -> float:
        return self._widest.front_chamfer

    @property
    def back_chamfer(self) -> float:
        return self._widest.back_chamfer

    def edge_z(self) -> tuple[float, float]:
        return self._widest.edge_z()

    def _boundary(self, r, order, side: str) -> np.ndarray:
        r = np.asarray(r, dtype=np.float64)
        z = np.full(r.shape, np.nan)
        for el in order:
            z = np.where(np.isnan(z) & (r <= el.outer_radius + 1e-12),
                         getattr(el, side)(np.minimum(r, el.outer_radius)), z)
        return np.where(np.isnan(z), getattr(self._widest, side)(np.minimum(r, self.outer_radius)), z)

    def front_z(self, r) -> np.ndarray:
        return self._boundary(r, self.elements, "front_z")

    def back_z(self, r) -> np.ndarray:
        return self._boundary(r, self.elements[::-1], "back_z")


__all__ = ["OpticalFace", "face_piece", "LensElement", "GroupOutline"]
