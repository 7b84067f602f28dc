"""First-order data of a lens whose surfaces do not share one axis, from real rays along the folded axis.

The axis is the chief ray of the on-axis field: the ray from the axial object point (a beam along +z
for an object at infinity) through the centre of the stop, found by Newton's method on its launch
point. The effective focal lengths are the small-angle real-ray derivative about it: rays parallel to
the chief ray in object space, offset by ±h along the entrance x and y axes, leave at angles u' to it
in the image frame, and f = -2h / (u'(+h) - u'(-h)) (the central difference cancels the aberration
of second order; h is 1e-6 of the stop's distance scale, far above rounding). A coaxial lens gives its
paraxial EFL (tests/optics/test_folded.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from lensmount.optics.paraxial import indices
from lensmount.optics.placement import coaxial_frames
from lensmount.optics.prescription import Prescription
from lensmount.optics.realrays import trace

_STEPS = 30
_TOL_MM = 1e-12
_FD_MM = 1e-6


@dataclass(frozen=True)
class FoldedAxis:
    """The chief ray of the on-axis field and the focal lengths about it.

    launch: (x, y) on surface 1's vertex plane where the chief ray starts (mm); direction its object-space
    direction; image_point the chief ray on the image plane (assembly frame, mm) and image_local the same in
    the image frame (x, y, mm); efl_x, efl_y the focal lengths for rays offset along x and y (mm)."""

    launch: tuple[float, float]
    direction: tuple[float, float, float]
    image_point: tuple[float, float, float]
    image_local: tuple[float, float]
    efl_x: float
    efl_y: float


def placed(p: Prescription) -> Prescription:
    """The lens with explicit frames (a coaxial lens gets identity frames at its vertices)."""
    return p if p.frames else replace(p, frames=coaxial_frames(p.vertex_z, p.image_z))


def folded_axis(p: Prescription, wavelength_um: float | None = None) -> FoldedAxis:
    """The chief ray of the on-axis field and the EFLs about it (see the module)."""
    p = placed(p)
    stop = p.stop_index
    frame = p.frames[stop]

    def rays(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        origins = np.column_stack([xy, np.zeros(len(xy))])
        if p.finite_object:
            d = origins - np.array([0.0, 0.0, -p.object_distance])
        else:
            d = np.tile([0.0, 0.0, 1.0], (len(xy), 1))
        return origins, d / np.linalg.norm(d, axis=1, keepdims=True)

    def at_stop(xy: np.ndarray) -> np.ndarray:
        o, d = rays(xy)
        r = trace(p, o, d, wavelength_um, clip=False, n_surfaces=stop + 1)
        local, _ = frame.to_local(r.points[stop], r.directions[stop])
        return local[:, :2]

    xy = np.zeros(2)
    for _ in range(_STEPS):   # Newton on the launch point: one 3-ray batch per step
        probe = np.array([xy, xy + [_FD_MM, 0.0], xy + [0.0, _FD_MM]])
        hits = at_stop(probe)
        miss = hits[0]
        if np.hypot(*miss) < _TOL_MM:
            break
        jac = np.column_stack([(hits[1] - hits[0]) / _FD_MM, (hits[2] - hits[0]) / _FD_MM])
        xy = xy - np.linalg.solve(jac, miss)
    o, d = rays(xy[None, :])
    scale = max(1.0, float(np.max(np.abs(np.array([f.origin for f in p.frames])))))
    h = _FD_MM * scale
    offsets = np.array([[0, 0, 0], [h, 0, 0], [-h, 0, 0], [0, h, 0], [0, -h, 0]], dtype=float)
    r = trace(p, o[0] + offsets, np.tile(d[0], (5, 1)), wavelength_um, clip=False)
    image = p.frames[-1]
    local, dirs = image.to_local(r.points[-1], r.directions[-1])
    chief = dirs[0]
    # the image frame's x and y, made square to the chief ray
    ex = np.array([1.0, 0.0, 0.0]) - chief[0] * chief
    ey = np.array([0.0, 1.0, 0.0]) - chief[1] * chief
    ex, ey = ex / np.linalg.norm(ex), ey / np.linalg.norm(ey)
    along = dirs @ chief
    ux, uy = dirs @ ex / along, dirs @ ey / along
    n_image = float(indices(p, r.wavelength_um)[-1])   # in an immersion medium f' = n' f
    efl_x = -2.0 * h / (n_image * (ux[1] - ux[2])) if ux[1] != ux[2] else math.inf
    efl_y = -2.0 * h / (n_image * (uy[3] - uy[4])) if uy[3] != uy[4] else math.inf
    return FoldedAxis((float(xy[0]), float(xy[1])), tuple(float(v) for v in d[0]),
                      tuple(float(v) for v in r.points[-1][0]), (float(local[0, 0]), float(local[0, 1])),
                      float(efl_x), float(efl_y))


__all__ = ["FoldedAxis", "folded_axis", "placed"]
