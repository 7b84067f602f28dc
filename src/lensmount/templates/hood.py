"""Front sun hood: a tube in front of the barrel (its vanes are separate parts)."""

from __future__ import annotations

from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Hood(RevolvedPart):
    """Args:
        z_front: z of the hood's mouth, mm. z_back: where it meets the barrel.
        inner_radius, outer_radius: mm.
    """

    z_front: float
    z_back: float
    inner_radius: float
    outer_radius: float

    def segments(self) -> list[Segment]:
        return polygon([(self.inner_radius, self.z_front), (self.inner_radius, self.z_back),
                        (self.outer_radius, self.z_back), (self.outer_radius, self.z_front)])


__all__ = ["Hood"]
