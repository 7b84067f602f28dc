"""Coordinate breaks in a .zmx: the frame of every surface (lensmount.optics.placement).

    TYPE COORDBRK  PARM 1/2 decentre x/y (lens units), PARM 3/4/5 tilt about x/y/z (degrees),
                   PARM 6 order (0: decentre then tilt x, y, z; otherwise tilt z, y, x then
                   decentre); its DISZ runs along the new z
    PPAR k s a b c parameter k picked up from surface s: a × (its parameter c, or k when c is 0) + b;
                   resolved here, in surface order (a return break: the same break scaled by -1,
                   the order toggled)
    SCBD b o _ dx dy tx ty tz  a surface's own tilt/decentre before it (order o as PARM 6): read on
                   the image surface, whose plane it turns (an off-axis parabola's image plane turned
                   90° to its focused beam: Edmund 37992); on any other surface an error, since the
                   return after the surface is not read
"""

from __future__ import annotations

import math

from lensmount.errors import InputError
from lensmount.optics.io.zemax_file import ImportNote
from lensmount.optics.placement import Frame


def break_values(lens, zs) -> tuple[float, ...]:
    """PARM 1..6 of a coordinate break with its PPAR pickups resolved."""
    by_number = {z.number: z for z in lens.surfaces}
    return tuple(_parameter(by_number, zs, k, set()) for k in range(1, 7))


def _parameter(by_number, zs, k: int, seen: set) -> float:
    if k not in zs.ppar or zs.number in seen:
        return zs.parm.get(k, (0.0, 0))[0]
    source, scale, offset, column = zs.ppar[k]
    if source not in by_number:
        return zs.parm.get(k, (0.0, 0))[0]
    return scale * _parameter(by_number, by_number[source], column or k, seen | {zs.number}) + offset


def frames(lens, file: str, notes: list) -> dict[int, Frame]:
    """The frame of every surface by its number (SURF 1 .. image; breaks included, at their vertex)."""
    s = lens.unit
    body, image = lens.surfaces[1:-1], lens.surfaces[-1]
    out: dict[int, Frame] = {}
    frame = Frame()
    for zs in (*body, image):
        if zs.scbd:
            if zs is not image:
                raise InputError(f"surface {zs.number} carries a tilt or decentre of its own (SCBD), which lensmount "
                                 "does not read", file=file, line=zs.scbd[1],
                                 valid="tilts and decentres as coordinate breaks (TYPE COORDBRK) around the surface")
            values = zs.scbd[0]
            order, (dx, dy, tx, ty, tz) = values[0], (tuple(values[2:7]) + (0.0,) * 5)[:5]
            frame = frame.broken(dx * s, dy * s, tx, ty, tz, order)
            notes.append(ImportNote("imported", f"SURF {zs.number}", f"the image plane's own tilt/decentre (SCBD, "
                                    f"before the surface): decentre {dx:g}, {dy:g}, tilt {tx:g}°, {ty:g}°, {tz:g}°"))
        out[zs.number] = frame
        if zs.type == "COORDBRK":
            dx, dy, tx, ty, tz, order = break_values(lens, zs)
            frame = frame.broken(dx * s, dy * s, tx, ty, tz, order)
        if zs is not image and math.isfinite(zs.thickness):   # an infinite one is refused by the reader
            frame = frame.advanced(zs.thickness * s)
    return out


__all__ = ["break_values", "frames"]
