"""Baffle vane: a thin annulus with a knife edge (land `edge_width`, role `vane-edge`)
facing the incoming light, bevelled on the image side."""

from __future__ import annotations

import math
from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Vane(RevolvedPart):
    """Args:
        z_front: z of the vane's object-side face, mm.
        inner_radius: bore (beam envelope + margin), mm.
        outer_radius: outside radius (the hood or spacer-tube bore), mm.
        thickness: axial thickness, mm.
        edge_width: axial width of the inner edge land, mm.
        bevel_angle_deg: bevel angle to the vane face.
    """

    z_front: float
    inner_radius: float
    outer_radius: float
    thickness: float = 1.0
    edge_width: float = 0.1
    bevel_angle_deg: float = 45.0

    def segments(self) -> list[Segment]:
        r0, R, z0 = self.inner_radius, self.outer_radius, self.z_front
        t, w = self.thickness, min(self.edge_width, self.thickness)
        run = (t - w) / math.tan(math.radians(self.bevel_angle_deg))
        run = min(run, 0.9 * (R - r0))  # keep a flat rear face on very short vanes
        pts = [(r0, z0), (r0, z0 + w), (r0 + run, z0 + t), (R, z0 + t), (R, z0)]
        return polygon(pts, ["vane-edge", "mount", "mount", "mount", "mount"])


__all__ = ["Vane"]
