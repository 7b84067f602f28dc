"""Rear detector housing: a can from the barrel's back to just behind the image
plane. Its bore clears the detector's corners; the detector itself is not a part
(the tracer models it analytically)."""

from __future__ import annotations

from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Housing(RevolvedPart):
    """Args:
        z_front: z where it meets the barrel. z_back_wall: z of the inner face of the back wall.
        inner_radius: bore, mm. wall: wall and back-wall thickness, mm.
    """

    z_front: float
    z_back_wall: float
    inner_radius: float
    wall: float

    def segments(self) -> list[Segment]:
        r, w = self.inner_radius, self.wall
        return polygon([(r, self.z_front), (r, self.z_back_wall), (0.0, self.z_back_wall),
                        (0.0, self.z_back_wall + w), (r + w, self.z_back_wall + w), (r + w, self.z_front)])


__all__ = ["Housing"]
