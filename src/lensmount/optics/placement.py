"""Where each surface sits when a lens does not share one axis: a frame per surface.

A frame is a rotation (its columns are the surface's local x, y, z axes in the assembly frame) and
an origin (the surface's vertex in the assembly frame, mm). Surface 1's frame is the identity at the
origin and light enters travelling +z, as for a coaxial lens; each gap runs along the local z of the
surface it follows, so a coaxial lens has identity rotations and origins (0, 0, vertex z).

Tilts follow the optical-design convention Zemax and rayoptics use: a positive tilt about x or y
turns the axes left-handed, about z right-handed (rayoptics.util.misc_math.euler2opt). A coordinate
break with order 0 decentres, then tilts about x, then the new y, then the new z; any other order
tilts about z, then y, then x, then decentres along the tilted axes (so a break with every value
negated and the order toggled undoes one, the return break of a fold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.errors import InputError

_IDENTITY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
_ON_AXIS_MM = 1e-9     # closer to the axis than this, a vertex is on it
_ALIGNED = 1e-12       # a rotation closer than this to the identity is none


@dataclass(frozen=True)
class Frame:
    """A surface's placement: `rotation` row-major 3x3 (columns: local x, y, z in the assembly
    frame) and `origin` (mm, assembly frame)."""

    rotation: tuple[float, ...] = _IDENTITY
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def matrix(self) -> np.ndarray:
        return np.array(self.rotation, dtype=np.float64).reshape(3, 3)

    @property
    def position(self) -> np.ndarray:
        return np.array(self.origin, dtype=np.float64)

    @property
    def axis(self) -> np.ndarray:
        """The local z axis in the assembly frame."""
        return self.matrix[:, 2]

    @property
    def is_axial(self) -> bool:
        """No tilt, and the vertex on the assembly z axis."""
        return (max(abs(a - b) for a, b in zip(self.rotation, _IDENTITY)) < _ALIGNED
                and math.hypot(self.origin[0], self.origin[1]) < _ON_AXIS_MM)

    def tilts_deg(self) -> tuple[float, float, float]:
        """(about x, about y, about z) in the break convention of order 0 that gives this rotation."""
        m = self.matrix
        # R = Rx(-a) Ry(-b) Rz(c): m[0,2] = -sin b, m[1,2] = -sin a cos b ... solved for a, b, c
        b = -math.asin(max(-1.0, min(1.0, m[0, 2])))
        a = math.atan2(m[1, 2], m[2, 2])
        c = math.atan2(-m[0, 1], m[0, 0])
        return math.degrees(a), math.degrees(b), math.degrees(c)

    def advanced(self, distance: float) -> "Frame":
        """The frame `distance` mm along its own z (a gap)."""
        return _frame(self.matrix, self.position + distance * self.axis)

    def broken(self, decenter_x: float, decenter_y: float, tilt_x: float, tilt_y: float, tilt_z: float,
               order: float = 0.0) -> "Frame":
        """The frame after a coordinate break (decentres mm, tilts in degrees)."""
        m, o = self.matrix, self.position
        rx, ry, rz = _rot(0, -tilt_x), _rot(1, -tilt_y), _rot(2, tilt_z)
        shift = np.array([decenter_x, decenter_y, 0.0])
        if order == 0:
            o = o + m @ shift
            return _frame(m @ rx @ ry @ rz, o)
        m = m @ rz @ ry @ rx
        return _frame(m, o + m @ shift)

    def to_local(self, points: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) points and directions from the assembly frame into this frame."""
        m = self.matrix
        return (points - self.position) @ m, directions @ m

    def to_global(self, points: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = self.matrix
        return points @ m.T + self.position, directions @ m.T


def _rot(axis: int, degrees: float) -> np.ndarray:
    """Right-handed rotation about a coordinate axis (columns: the turned axes)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def _frame(m: np.ndarray, o: np.ndarray) -> Frame:
    return Frame(tuple(float(v) for v in m.reshape(-1)), tuple(float(v) for v in o))


def coaxial_frames(vertex_z, image_z: float) -> tuple[Frame, ...]:
    """The frames of a coaxial lens: identity rotations on the z axis, the image plane's last."""
    return tuple(Frame(origin=(0.0, 0.0, float(z))) for z in (*vertex_z, image_z))


def require_coaxial(prescription, what: str) -> None:
    """The one paragraph for the parts of lensmount that need every surface on one axis."""
    if prescription.frames:
        raise InputError(
            f"the lens '{prescription.name}' is folded, tilted or decentred (its surfaces do not share one axis: "
            f"see `lensmount inspect` for their frames); for {what}, every surface must be centred on one axis",
            valid="a lens whose surfaces share one axis; a folded or off-axis lens can be inspected "
                  "(`lensmount inspect`), not yet mounted, traced for stray light or simulated")


__all__ = ["Frame", "coaxial_frames", "require_coaxial"]
