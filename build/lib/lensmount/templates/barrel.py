"""Barrel: a tube whose stepped bore holds the lens groups, with integral seats.

The bore is given as an (r, z) polyline from the front to the back (computed in
lensmount.cad.layout: a cylinder around each lens group, radial steps, shoulder
rings that touch a lens at its contact height, end lips). The outside is one
cylinder of radius `outer_radius`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Barrel(RevolvedPart):
    """Args:
        bore: ((r, z), ...) inner boundary from the front face to the back face, mm.
        outer_radius: outside radius, mm.
    """

    bore: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    outer_radius: float = 0.0

    def segments(self) -> list[Segment]:
        pts = list(self.bore)
        z_front, z_back = pts[0][1], pts[-1][1]
        pts += [(self.outer_radius, z_back), (self.outer_radius, z_front)]
        return polygon(pts)


__all__ = ["Barrel"]
