"""Mirror element: a solid of revolution with a reflecting face, for catadioptric lenses.

Two kinds, one template:

* a front-surface mirror: the coated face and a flat back (`back` None, `back_z` the
  plane), the blank `thickness` deep on the side away from the light;
* a Mangin mirror (or any element with a central hole): glass between two optical faces,
  the coated one reflecting from inside.

A face is optical (tagged with its surface index) only out to its `coated` radius: a
mirror reflects where it is coated, the ring beyond is the blank's polished bevel (role
`bevel`), so the clear aperture the file gives is the mirror's stop, not the blank's edge.
A central hole (`hole_radius` > 0) lets the light through that another pass brings
back along the axis (a Cassegrain's image behind its primary).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.templates.lens_element import OpticalFace, face_params, face_piece
from lensmount.templates.profile import RevolvedPart, Segment


@dataclass
class MirrorElement(RevolvedPart):
    """Args:
        front: the object-side face (smaller z) or None for a flat face at `front_z_flat`.
        back: the image-side face or None for a flat face at `back_z_flat`.
        outer_radius: the blank's edge radius, mm.
        hole_radius: central hole, mm (0: none).
        front_coated, back_coated: radius out to which each face is optical (None: all of it).
        front_z_flat, back_z_flat: z of a flat (non-optical) face, mm.
    """

    front: OpticalFace | None
    back: OpticalFace | None
    outer_radius: float
    hole_radius: float = 0.0
    front_coated: float | None = None
    back_coated: float | None = None
    front_z_flat: float = 0.0
    back_z_flat: float = 0.0

    def front_z(self, r) -> np.ndarray:
        r = np.asarray(r, dtype=np.float64)
        return self.front.z(r) if self.front is not None else np.full(r.shape, self.front_z_flat)

    def back_z(self, r) -> np.ndarray:
        r = np.asarray(r, dtype=np.float64)
        return self.back.z(r) if self.back is not None else np.full(r.shape, self.back_z_flat)

    def _pieces(self, face, coated, z_flat, reverse: bool) -> list[Segment]:
        h, R = self.hole_radius, self.outer_radius
        if face is None:
            segs = [Segment("line", ((h, z_flat), (R, z_flat)), "mount")]
        else:
            c = R if coated is None else min(max(coated, h), R)
            segs = [face_piece(face, h, c)]
            if c < R - 1e-9:
                segs.append(face_piece(face, c, R, "bevel"))
        if reverse:
            segs = [Segment(s.kind, tuple(s.points[::-1]), s.role, s.surface) for s in segs[::-1]]
        return segs

    def segments(self) -> list[Segment]:
        R, h = self.outer_radius, self.hole_radius
        segs = self._pieces(self.front, self.front_coated, self.front_z_flat, False)
        zf, zb = float(self.front_z(R)), float(self.back_z(R))
        segs.append(Segment("line", ((R, zf), (R, zb)), "lens-edge"))
        segs += self._pieces(self.back, self.back_coated, self.back_z_flat, True)
        # the hole's bore (a face), or the axis (no face)
        segs.append(Segment("line", ((h, float(self.back_z(h))), (h, float(self.front_z(h)))),
                            "lens-edge" if h > 0 else "mount"))
        return segs

    def thickness_at(self, r) -> np.ndarray:
        return self.back_z(r) - self.front_z(r)

    def params(self) -> dict:
        d = super().params()
        for key in ("front", "back"):
            if d[key] is not None:
                face_params(d[key])
        return d


__all__ = ["MirrorElement"]
