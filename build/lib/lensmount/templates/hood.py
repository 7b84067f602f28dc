"""Front sun hood: a tube in front of the barrel (its vanes are separate parts).

When the hood is wider than the barrel, a flange at its back closes the annulus
between them: it lies flat on the barrel's front face, so no light leaks around.
"""

from __future__ import annotations

from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Hood(RevolvedPart):
    """Args:
        z_front: z of the hood's mouth, mm. z_back: where it meets the barrel.
        inner_radius, outer_radius: mm.
        flange_radius: bore of the back flange (None = no flange), mm.
        flange_thickness: axial thickness of the flange, mm.
    """

    z_front: float
    z_back: float
    inner_radius: float
    outer_radius: float
    flange_radius: float | None = None
    flange_thickness: float = 2.0

    def segments(self) -> list[Segment]:
        ri, ro, z0, z1 = self.inner_radius, self.outer_radius, self.z_front, self.z_back
        if self.flange_radius is None:
            return polygon([(ri, z0), (ri, z1), (ro, z1), (ro, z0)])
        rf, zf = self.flange_radius, z1 - self.flange_thickness
        return polygon([(ri, z0), (ri, zf), (rf, zf), (rf, z1), (ro, z1), (ro, z0)])


__all__ = ["Hood"]
