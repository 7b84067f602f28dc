"""A template kind added the way docs/architecture.md says ("Where to add a template"): this file
only. A knife-edged baffle ring: a flat washer whose bore is a knife edge (role `vane-edge`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment


@dataclass
class KnifeRing(RevolvedPart):
    z: float  # mm, the flat back face
    bore_radius: float  # mm, the knife edge
    outer_radius: float
    thickness: float
    bevel_deg: float = 45.0  # the front face rises from the edge at this angle

    def segments(self) -> list[Segment]:
        run = self.thickness / math.tan(math.radians(self.bevel_deg))  # the bevel's radial length
        edge, bevel_top = (self.bore_radius, self.z), (self.bore_radius + run, self.z - self.thickness)
        front_out, back_out = (self.outer_radius, self.z - self.thickness), (self.outer_radius, self.z)
        return [
            Segment("line", (edge, bevel_top), role="vane-edge"),
            Segment("line", (bevel_top, front_out)),
            Segment("line", (front_out, back_out)),
            Segment("line", (back_out, edge)),
        ]
