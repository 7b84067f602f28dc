"""Cells for catadioptric lenses: a ring that holds one element (or a tube that holds a
group) with a front lip and a back support, and, for a cell in the middle of the beam
(a Cassegrain's secondary), a spider of thin radial vanes to the barrel.

The ring is drawn as a closed (r, z) polygon (lensmount.cad.catadioptric computes it
from the element's faces, staying `seats.clearance_mm` off the glass). The spider's
vanes are the one part of a mount that is not a solid of revolution: they are boxes
fused to the ring, their faces tagged `mount` (nothing in the profile matches them),
and the tracer meets them as triangles like any other face. They stand in the beam by
design: the profile checks see the ring alone (`segments`), the vanes are reported as
an obscuration, not a clash.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from lensmount.templates.profile import RevolvedPart, Segment, polygon, revolve


@dataclass
class Cell(RevolvedPart):
    """Args:
        outline: ((r, z), ...) the ring's closed profile, mm.
    """

    outline: tuple[tuple[float, float], ...] = field(default_factory=tuple)

    def segments(self) -> list[Segment]:
        return polygon(self.outline)

    @property
    def outer_radius(self) -> float:
        return max(r for r, _ in self.outline)


@dataclass
class SpiderCell(Cell):
    """A cell on `vanes` radial vanes (thickness `vane_thickness`, from the ring's outside
    to `reach` mm from the axis, over z in [z0, z1]); vane 1 along +x."""

    vanes: int = 3
    vane_thickness: float = 0.5
    reach: float = 0.0
    z0: float = 0.0
    z1: float = 0.0

    def vane_boxes(self) -> list[tuple[float, float, float]]:
        """(inner radius, outer radius, azimuth deg) of each vane: the inner end sunk half a
        thickness into the ring so the fuse is one solid, the outer corners inside `reach`."""
        half = 0.5 * self.vane_thickness
        r_out = math.sqrt(max(self.reach ** 2 - half ** 2, 0.0))
        r_in = self.outer_radius - half
        return [(r_in, r_out, 360.0 * k / self.vanes) for k in range(self.vanes)]

    def build(self):
        # lazy: build123d/OCP take seconds to load; planning a layout does without them
        from build123d import Box, Location, Rotation

        solid = revolve(self.segments())
        for r_in, r_out, az in self.vane_boxes():
            box = Box(r_out - r_in, self.vane_thickness, self.z1 - self.z0)
            placed = Rotation(0, 0, az) * Location((0.5 * (r_in + r_out), 0.0, 0.5 * (self.z0 + self.z1))) * box
            solid = solid.fuse(placed)
        solids = solid.solids()
        return solids[0] if len(solids) == 1 else solid.clean()


__all__ = ["Cell", "SpiderCell"]
