"""Retaining ring: a threaded ring pressing a lens group from one side.

It touches the lens at the contact height (inner corner) with the same cone rule
as a spacer end; its other face is flat, `thickness` from the cone's far end.
"""

from __future__ import annotations

from dataclasses import dataclass

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Retainer(RevolvedPart):
    """A retaining ring.

    Args:
        contact_r: radius of the inner corner touching the lens, mm.
        contact_z: axial position of that corner, mm.
        slope: contact-face cone slope (z moves away from the lens by slope per mm outward).
        side: -1 when the ring is in front of the lens (object side), +1 behind it.
        outer_radius: thread (outside) radius, mm.
        thickness: axial thickness at the outside, mm.
        far_r: bore radius at the far face (the bore opens conically when the beam
            grows away from the lens); None = contact_r.
    """

    contact_r: float
    contact_z: float
    slope: float
    side: int
    outer_radius: float
    thickness: float
    far_r: float | None = None

    def contact_face_z(self, r):
        # away from the lens: toward -z for a ring in front (side -1), +z behind (the spacer's rule)
        return self.contact_z + self.side * self.slope * (r - self.contact_r)

    def far_face_z(self) -> float:
        """z of the flat face away from the lens."""
        return float(self.contact_face_z(self.outer_radius)) + self.side * self.thickness

    def segments(self) -> list[Segment]:
        R = self.outer_radius
        zc_out = float(self.contact_face_z(R))
        zf = self.far_face_z()
        return polygon([(self.contact_r, self.contact_z), (R, zc_out), (R, zf),
                        (self.contact_r if self.far_r is None else self.far_r, zf)])


__all__ = ["Retainer"]
