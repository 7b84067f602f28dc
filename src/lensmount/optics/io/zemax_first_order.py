"""A .zmx file's system aperture and fields, turned into what a Prescription holds.

Zemax states the aperture and the fields in several ways; lensmount keeps one of each:
an entrance pupil diameter, an image-space F/# or (finite objects) an object-space
NA; field angles for an object at infinity, object heights for a finite one. The
conversions use the lens itself (paraxial data, and real chief rays for real image
heights), so they run once the surfaces are known.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from lensmount.errors import InputError
from lensmount.optics.io.zemax_file import ImportNote
from lensmount.optics.paraxial import marginal_heights, marginal_start, paraxial, surface_matrices
from lensmount.optics.prescription import Aperture, Prescription
from lensmount.optics.realrays import chief_ray

_FIELD_TYPES = {0: "angles (deg)", 1: "object heights", 2: "paraxial image heights", 3: "real image heights"}
_REAL_HEIGHT_STEPS = 30


def apply_aperture_and_fields(base: Prescription, lens, numbers, notes, file) -> Prescription:
    """`base` (surfaces, wavelengths, object distance) completed with the file's aperture and fields."""
    stops = [i for i, s in enumerate(base.surfaces) if s.is_stop]
    if not stops:
        raise InputError("no surface is marked as the aperture stop", file=file,
                         valid="a STOP line on one of SURF 1..N-1")
    p = _with_aperture(base, lens, notes, file)
    return _with_fields(p, lens, notes, file)


def _with_aperture(p: Prescription, lens, notes, file) -> Prescription:
    if lens.aperture is None:
        raise InputError("no system aperture", file=file,
                         valid="ENPD, FNUM, OBNA or FLOA (Zemax's system aperture)")
    kind, value, ln = lens.aperture
    finite = p.finite_object
    if kind != "float" and not (value > 0 and math.isfinite(value)):
        raise InputError(f"aperture value {value} is not positive", file=file, line=ln, valid="a value > 0")
    if kind == "epd":
        out = Aperture("epd", value * lens.unit)
        text = f"entrance pupil diameter {out.value:g} mm"
    elif kind == "fno" or (kind == "working_fno" and not finite):
        # at infinity the paraxial working F/# 1/(2 n' u') equals efl / epd
        out = Aperture("fno", value)
        text = f"{'image-space' if kind == 'fno' else 'paraxial working'} F/# {value:g}"
    elif kind == "working_fno":
        # 1 / (2 |n'u'|) scales as 1 / epd: trace the marginal ray for epd = 1 and rescale
        nu = _image_marginal_slope(replace(p, aperture=Aperture("epd", 1.0)))
        out = Aperture("epd", 1.0 / (2.0 * value * abs(nu)))
        text = f"paraxial working F/# {value:g} -> entrance pupil diameter {out.value:.6g} mm"
    elif kind in ("object_na", "object_cone_deg"):
        if not finite:
            raise InputError("an object-space NA needs an object at a finite distance", file=file, line=ln,
                             valid="ENPD or FNUM for an object at infinity (DISZ INFINITY on SURF 0)")
        na = value if kind == "object_na" else math.sin(math.radians(value))
        if na >= 1.0:
            raise InputError(f"object-space NA {na:g} is not below 1", file=file, line=ln, valid="0 < NA < 1 (in air)")
        out = Aperture("object_na", na)
        text = f"object-space NA {na:g}" + ("" if kind == "object_na" else f" (cone half-angle {value:g}°)")
    else:  # float by stop size: the stop's own semi-diameter sets the pupil
        stop = p.surfaces[p.stop_index]
        if stop.clear_semi_diameter is None:
            raise InputError("the aperture floats by stop size but the stop has no semi-diameter", file=file,
                             line=ln, valid="a DIAM line on the STOP surface")
        unit = paraxial(replace(p, aperture=Aperture("epd", 1.0))).stop_semi_diameter
        out = Aperture("epd", stop.clear_semi_diameter / unit)
        text = f"float by stop size {stop.clear_semi_diameter:g} mm -> entrance pupil diameter {out.value:.6g} mm"
    notes.append(ImportNote("imported", "aperture", text))
    return _admitted_by_the_stop(replace(p, aperture=out), lens, notes)


def _admitted_by_the_stop(p: Prescription, lens, notes) -> Prescription:
    """The working aperture when a circular aperture (CLAP) on the stop surface is smaller than the
    beam the system aperture sends through it: OpticStudio keeps the stated pupil for its paraxial data
    and lets the stop's aperture vignette the real rays, so the beam that passes is the pupil the
    aperture admits (paraxially scaled, as float by stop size scales it); lensmount takes that as the
    pupil, so the diaphragm, the envelope and the F/# are those of the light that gets through."""
    stop = next((zs for zs in lens.surfaces if zs.stop), None)
    if p.aperture.kind not in ("epd", "fno") or stop is None or not stop.clap:
        return p
    par = paraxial(p)
    clap = stop.clap * lens.unit
    if par.stop_semi_diameter <= clap * (1.0 + 1e-9):
        return p
    epd = par.epd * clap / par.stop_semi_diameter
    notes.append(ImportNote("substituted", "aperture",
                      f"entrance pupil diameter {par.epd:.6g} mm fills the stop (SURF {stop.number}) to "
                      f"{par.stop_semi_diameter:.4g} mm, beyond its circular aperture {clap:.4g} mm, which clips "
                      f"the beam -> the entrance pupil that aperture admits: {epd:.6g} mm "
                      f"(F/# {abs(par.efl) / epd:.4g} at infinity)"))
    return replace(p, aperture=Aperture("epd", epd))


def _image_marginal_slope(p: Prescription) -> float:
    """n'u' of the paraxial marginal ray after the last surface (p's aperture)."""
    refr, trans = surface_matrices(p, p.primary_wavelength_um)
    v = np.array([marginal_heights(p)[0], _start_slope(p, paraxial(p))])
    for i in range(len(p.surfaces)):
        if i > 0:
            v = trans[i - 1] @ v
        v = refr[i] @ v
    return float(v[1])


def _start_slope(p: Prescription, par) -> float:
    return marginal_start(p, par.epd, par.entrance_pupil_z)[1]


def _with_fields(p: Prescription, lens, notes, file) -> Prescription:
    n = lens.n_fields or max(len(lens.yfields), len(lens.xfields), 1)
    ys = (lens.yfields + [0.0] * n)[:n]
    xs = (lens.xfields + [0.0] * n)[:n]
    kind = lens.field_type
    if kind == 0:
        # The lens is rotationally symmetric: a field (x, y) is the radial angle with
        # tan^2 = tan^2 x + tan^2 y, and only its magnitude matters.
        values = [math.degrees(math.atan(math.hypot(math.tan(math.radians(x)), math.tan(math.radians(y)))))
                  for x, y in zip(xs, ys)]
    else:
        values = [math.hypot(x, y) * lens.unit for x, y in zip(xs, ys)]
    factors = _vignetting(lens, xs, ys, n, notes)
    if factors:
        keep = _unique_index(values)
        values, factors = [round(float(values[k]), 12) for k in keep], [factors[k] for k in keep]
    else:
        values = _unique(values)
    if kind == 1 and not p.finite_object:
        raise InputError("fields are object heights but the object is at infinity", file=file,
                         line=lens.field_type_line, valid="FTYP 0 (angles) for an object at infinity")
    par = paraxial(p)
    if kind == 2 and not p.finite_object:
        values = [math.degrees(math.atan(h / abs(par.efl))) for h in values]  # h' = f tan(theta)
    elif kind == 2:
        values = [h / _paraxial_scale(p, par) for h in values]
    elif kind == 3:
        values = _real_image_height_fields(p, values, par, file, lens.field_type_line)
    if p.finite_object:
        d = p.object_distance + par.entrance_pupil_z
        if not abs(d) > 1e-9 * max(1.0, abs(p.object_distance)):
            raise InputError(f"the object lies in the entrance pupil (object distance {p.object_distance:g} mm, the "
                             f"pupil {par.entrance_pupil_z:g} mm from the first surface): a field has no angle there",
                             file=file, line=lens.surfaces[0].thickness_line if lens.surfaces else None,
                             valid="SURF 0's DISZ placing the object away from the entrance pupil, or INFINITY")
        # OpticStudio measures a field angle from the paraxial entrance pupil's centre on the axis:
        # the object point of angle theta is d tan(theta) high (Thorlabs MAP105050-A: 4° -> 3.629 mm,
        # its SURF 0 DIAM)
        heights = tuple(d * math.tan(math.radians(v)) for v in values) if kind == 0 else tuple(values)
        angles = tuple(_unique([math.degrees(math.atan(h / d)) for h in heights]))
        out = replace(p, object_heights_mm=heights, field_angles_deg=angles)
        shown = ", ".join(f"{h:.4g}" for h in heights) + " mm object heights"
    else:
        out = replace(p, field_angles_deg=tuple(values))
        shown = ", ".join(f"{a:.4g}" for a in values) + "° field angles"
    out = replace(out, vignetting=tuple(factors))
    given = ", ".join(f"{math.hypot(x, y):g}" for x, y in zip(xs, ys))
    text = f"fields as {_FIELD_TYPES[kind]} {given}" + ("" if kind == 1 or (kind == 0 and not p.finite_object) else f" -> {shown}")
    notes.append(ImportNote("imported", "fields", text))
    return out


def _paraxial_scale(p: Prescription, par) -> float:
    """|paraxial magnification| of a finite object (Lagrange: m = n u / n'u' of the marginal ray)."""
    nu_image = _image_marginal_slope(p)
    return abs(_start_slope(p, par) / nu_image) if nu_image else 1.0


def _real_image_height_fields(p: Prescription, heights, par, file, line) -> list[float]:
    """Field values whose real chief rays land at the given image heights (secant iteration)."""
    target = np.asarray(heights, dtype=np.float64)
    guess = (np.degrees(np.arctan(target / abs(par.efl))) if not p.finite_object
             else target / _paraxial_scale(p, par))
    x0, x1 = guess * 0.999, guess
    f0 = _chief_height(chief_ray, p, x0) - target
    for _ in range(_REAL_HEIGHT_STEPS):
        f1 = _chief_height(chief_ray, p, x1) - target
        if np.all(np.abs(f1) < 1e-9 * np.maximum(1.0, np.abs(target))):
            return [float(v) for v in x1]
        den = np.where(np.abs(f1 - f0) > 1e-300, f1 - f0, 1.0)
        x0, x1, f0 = x1, np.where(np.abs(f1 - f0) > 1e-300, x1 - f1 * (x1 - x0) / den, x1), f1
    raise InputError("no real chief ray reaches the field's image height", file=file, line=line,
                     valid="real image heights the lens can form (FTYP 3)")


def _chief_height(chief_ray, p: Prescription, values) -> np.ndarray:
    r = chief_ray(p, np.asarray(values, dtype=np.float64), clip=False)
    h = np.hypot(r.image_points[:, 0], r.image_points[:, 1])
    return np.where(np.asarray(values) == 0.0, 0.0, h)


def _vignetting(lens, xs, ys, n, notes) -> list[tuple[float, ...]]:
    """Per field, the file's vignetting factors in lensmount's frame (the field along +y), or [].

    Zemax's +y field angle and lensmount's field both send the light upward, but a +y object
    height sits where lensmount puts a negative field: heights mirror VDY and VAN."""
    rows = [[(lens.vignetting.get(key, []) + [0.0] * n)[k] for key in ("VDX", "VDY", "VCX", "VCY", "VAN")]
            for k in range(n)]
    if not any(any(r) for r in rows):
        return []
    out = []
    for (x, y), (vdx, vdy, vcx, vcy, van) in zip(zip(xs, ys), rows):
        if x != 0.0 and any((vdx, vdy, vcx, vcy, van)):
            notes.append(ImportNote("ignored", "fields", "vignetting factors: a vignetted field off the y axis "
                              f"(x = {x:g}) has no rotationally symmetric counterpart; the automatic "
                              "semi-diameters come from the unvignetted beam"))
            return []
        flip = -1.0 if (y < 0.0) != (lens.field_type != 0) else 1.0
        out.append((vdx, flip * vdy, vcx, vcy, flip * van))
    notes.append(ImportNote("imported", "fields", "vignetting factors (VDX, VDY, VCX, VCY, VAN) "
                      + "; ".join(f"{math.hypot(x, y):g}: " + ", ".join(f"{v:.4g}" for v in r)
                                  for (x, y), r in zip(zip(xs, ys), rows))
                      + ": the automatic semi-diameters come from the beam they leave"))
    return out


def _unique_index(values) -> list[int]:
    """Indices of the first occurrence of each value (to 1e-12)."""
    seen, out = set(), []
    for k, v in enumerate(values):
        v = round(float(v), 12)
        if v not in seen:
            seen.add(v)
            out.append(k)
    return out


def _unique(values) -> list[float]:
    return [round(float(values[k]), 12) for k in _unique_index(values)]


__all__ = ["apply_aperture_and_fields"]
