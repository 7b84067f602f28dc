"""Rear detector housing: a can from the barrel's back to just behind the image
plane. Its bore clears the detector's corners; the detector itself is not a part
(the tracer models it analytically). When the can is wider than the barrel, a
front flange lies on the barrel's back face so the can is closed."""

from __future__ import annotations

from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Housing(RevolvedPart):
    """Args:
        z_front: z where it meets the barrel. z_back_wall: z of the inner face of the back wall.
        inner_radius: bore, mm. wall: wall, back-wall and flange thickness, mm.
        flange_radius: bore of the front flange (None = no flange), mm.
    """

    z_front: float
    z_back_wall: float
    inner_radius: float
    wall: float
    flange_radius: float | None = None

    def segments(self) -> list[Segment]:
        r, w = self.inner_radius, self.wall
        front = [(r, self.z_front)] if self.flange_radius is None else \
            [(self.flange_radius, self.z_front), (self.flange_radius, self.z_front + w), (r, self.z_front + w)]
        return polygon(front + [(r, self.z_back_wall), (0.0, self.z_back_wall), (0.0, self.z_back_wall + w),
                                (r + w, self.z_back_wall + w), (r + w, self.z_front)])


__all__ = ["Housing"]
