"""Spacer: a ring between two lens groups (or a lens and the diaphragm).

Each end touches its neighbour at the mechanical contact height `h` (the spacer's
inner corner). The end face is a cone z = z_c ± m (r − h) whose slope m keeps it off
the glass everywhere outside the contact: m = 0 (a flat end, sharp-corner contact)
on a surface convex toward the spacer, the smallest safe slope on a concave one,
the surface's own slope at h for tangent contact (lensmount.cad.layout picks m).
The length therefore follows from the vertex gap and both surfaces' sag at the
contact heights. A long spacer becomes a tube with inward lips at both ends (the
contacts) and room inside for vanes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.templates.profile import RevolvedPart, Segment, polygon


@dataclass
class Spacer(RevolvedPart):
    """A spacer ring.

    Args:
        front_r: radius of the inner corner touching the object-side neighbour, mm.
        front_z: axial position of that corner, mm.
        front_slope: end-face cone slope at the front (z grows outward by front_slope per mm;
            negative for tangent contact on a surface convex toward the spacer).
        back_r: radius of the inner corner touching the image-side neighbour, mm.
        back_z: axial position of that corner, mm.
        back_slope: end-face cone slope at the back (z shrinks outward by back_slope per mm).
        outer_radius: outside radius, mm.
        tube_radius: bore of a long spacer between its end lips; None = straight bore
            from corner to corner.
        lip: axial thickness of the end lips (tube only), mm.
    """

    front_r: float
    front_z: float
    front_slope: float
    back_r: float
    back_z: float
    back_slope: float
    outer_radius: float
    tube_radius: float | None = None
    lip: float = 2.0

    def front_face_z(self, r):
        return self.front_z + self.front_slope * (r - self.front_r)

    def back_face_z(self, r):
        return self.back_z - self.back_slope * (r - self.back_r)

    def min_length(self) -> float:
        """Shortest axial extent (at the outside or the inner corners), mm."""
        R = self.outer_radius
        return float(min(self.back_face_z(R) - self.front_face_z(R), self.back_z - self.front_z))

    def inner_radius_at(self, z):
        """Bore radius at z (for vanes inside and beam checks)."""
        z = np.asarray(z, dtype=np.float64)
        if self.tube_radius is not None:
            r = np.full(z.shape, float(self.tube_radius))
            r = np.where(z <= self.front_z + self.lip, self.front_r, r)
            return np.where(z >= self.back_z - self.lip, self.back_r, r)
        f = np.clip((z - self.front_z) / max(self.back_z - self.front_z, 1e-12), 0.0, 1.0)
        return self.front_r + f * (self.back_r - self.front_r)

    def segments(self) -> list[Segment]:
        R = self.outer_radius
        pts = [(self.front_r, self.front_z), (R, self.front_face_z(R)),
               (R, self.back_face_z(R)), (self.back_r, self.back_z)]
        if self.tube_radius is not None:
            t = self.tube_radius
            pts += [(self.back_r, self.back_z - self.lip), (t, self.back_z - self.lip),
                    (t, self.front_z + self.lip), (self.front_r, self.front_z + self.lip)]
        return polygon(pts)


__all__ = ["Spacer"]
