"""Rear baffle: a cold-stop style tube inside the detector housing, from the barrel's back
face to just in front of the detector, whose bore follows the converging beam (the real-ray
envelope + a margin, a polyline through samples of it). Light the lens sends outside the
field (the sun's image beside the detector, ghosts) meets its bore near the beam instead
of the housing's wide walls."""

from __future__ import annotations

from dataclasses import dataclass, field

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class RearBaffle(RevolvedPart):
    """Args:
        bore: ((r, z), ...) the bore from the front end to the back end, mm.
        outer_radius: outside radius (it sits in the housing's bore), mm.
    """

    bore: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    outer_radius: float = 0.0

    @property
    def z_front(self) -> float:
        return float(self.bore[0][1])

    @property
    def z_back(self) -> float:
        return float(self.bore[-1][1])

    def segments(self) -> list[Segment]:
        pts = list(self.bore)
        return polygon(pts + [(self.outer_radius, self.z_back), (self.outer_radius, self.z_front)])


__all__ = ["RearBaffle"]
