"""Aperture diaphragm: a plate at the stop with a knife edge.

The bore is a cylindrical land of axial width `land` (the seed paper's 50 µm
edge, role `diaphragm-edge`) centred on the stop plane; a bevel at
`bevel_angle` to the plate face opens from the land to the full thickness on
one side, so the light meets only the land.

On a stop that is a curved lens face the plate cannot lie on the stop: its land
sits where that face crosses the pupil's edge and both plate faces are cones of
slope `slope` (dz/dr) that keep the plate off the glass outward of the land.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Diaphragm(RevolvedPart):
    """Args:
        z_stop: stop plane z, mm (the land is centred on it).
        inner_radius: stop clear semi-diameter, mm.
        outer_radius: outside radius, mm.
        thickness: plate thickness, mm.
        land: axial width of the knife-edge land, mm.
        bevel_angle_deg: bevel angle to the plate face, degrees.
        bevel_side: "rear" (bevel faces the image) or "front".
        slope: dz/dr of both plate faces outward of the land (0: a flat plate).
    """

    z_stop: float
    inner_radius: float
    outer_radius: float
    thickness: float = 1.0
    land: float = 0.05
    bevel_angle_deg: float = 45.0
    bevel_side: str = "rear"
    slope: float = 0.0

    def bevel_run(self) -> float:
        """Radial extent of the bevel, mm."""
        return (self.thickness - self.land) / math.tan(math.radians(self.bevel_angle_deg))

    def z_range(self) -> tuple[float, float]:
        """(front face z, back face z) at the land's radius (faces extended to it)."""
        if self.bevel_side == "rear":
            z0 = self.z_stop - 0.5 * self.land
            return z0, z0 + self.thickness
        z1 = self.z_stop + 0.5 * self.land
        return z1 - self.thickness, z1

    def land_range(self) -> tuple[float, float, float]:
        """(z0, z1, radius) of the land: the bore that is the aperture stop."""
        return self.z_stop - 0.5 * self.land, self.z_stop + 0.5 * self.land, self.inner_radius

    def face_inner_radius(self, side: str) -> float:
        """Inner radius of the flat front or rear face (where a spacer may touch)."""
        return self.inner_radius + (self.bevel_run() if side == self.bevel_side else 0.0)

    def face_z(self, side: str, r):
        """z of the front or rear plate face at radius r (its cone extended inward to the land)."""
        z0, z1 = self.z_range()
        return (z0 if side == "front" else z1) + self.slope * (r - self.inner_radius)

    def segments(self) -> list[Segment]:
        r0, R = self.inner_radius, self.outer_radius
        z0, z1 = self.z_range()
        run, dz = self.bevel_run(), self.slope
        if self.bevel_side == "rear":
            pts = [(r0, z0), (r0, z0 + self.land), (r0 + run, z1 + dz * run), (R, z1 + dz * (R - r0)),
                   (R, z0 + dz * (R - r0))]
        else:
            pts = [(r0 + run, z0 + dz * run), (r0, z1 - self.land), (r0, z1), (R, z1 + dz * (R - r0)),
                   (R, z0 + dz * (R - r0))]
        roles = ["diaphragm-edge", "mount", "mount", "mount", "mount"]
        if self.bevel_side == "front":
            roles = ["mount", "diaphragm-edge", "mount", "mount", "mount"]
        return polygon(pts, roles)


__all__ = ["Diaphragm"]
