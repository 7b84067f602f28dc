"""Paraxial (first-order) properties of a prescription, derived on demand.

Each surface is a 2x2 matrix acting on (y, n·u): refraction [[1, 0], [-phi, 1]]
with power phi = (n' - n)·c, transfer over a gap t in index n [[1, t/n], [0, 1]].
Mirrors use the usual signed-index rule: the index changes sign at each reflection
(n' = -n), so a mirror's power is -2 n c and the negative thicknesses after it give
positive reduced thicknesses t/n'. Object at infinity or at `object_distance`.
All z in the assembly frame (surface 1 vertex at z = 0).

Definitions (Zemax's, for an object at infinity):
    efl = -1 / C of the whole system, referred to air (OpticStudio's EFL "in air"); in an image
          medium of index n' (an immersion objective) the rear focal length is n' efl
          (`image_space_focal_length`, OpticStudio's "in image space") and the paraxial focus lies
          n' times further from the rear principal plane than in air
    image_na = n' u' of the marginal ray after the last surface: EPD / (2 efl) for an object at
          infinity whatever n' (the medium shrinks the angle, not the NA)
    bfl = distance from the last vertex to the paraxial focus
    f_number = efl / epd (image-space F/#; for an object at infinity it equals
               the paraxial working F/# 1 / (2 n' u'))
    entrance pupil = paraxial image of the stop through the surfaces in front of it
    exit pupil = paraxial image of the stop through the surfaces behind it

Afocal: a system whose power is below AFOCAL_POWER_RATIO of the sum of its surfaces' powers
|phi_i| (a telescope, a relay to infinity, a zero-power corrector) forms no image at a finite
distance: its EFL and F/# mean nothing (the rounding of the file's data makes them 1e6 mm and
F/1e6), and it is described by its angular magnification instead, D of the system matrix
[[A, B], [C ~ 0, D]] (n u' = D n u; air on both sides).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.optics.glass import refractive_index
from lensmount.optics.prescription import Prescription

_TINY = 1e-300
FAR_PUPIL_DISTANCES = 1e3    # an entrance pupil this many object distances away is at infinity (telecentric)
MAX_OBJECT_ANGLE_DEG = 80.0  # object_height_at's angle from surface 1, at most
AFOCAL_POWER_RATIO = 1e-4


@dataclass(frozen=True)
class Paraxial:
    """First-order data of a lens (mm, assembly frame).

    efl: effective focal length.
    bfl: back focal length, last vertex to paraxial focus.
    epd: entrance pupil diameter (given, or efl / f-number).
    f_number: image-space F/# = efl / epd.
    entrance_pupil_z, exit_pupil_z: pupil positions.
    entrance_pupil_diameter is `epd`; exit_pupil_diameter: paraxial image of the stop.
    stop_semi_diameter: paraxial marginal-ray height at the stop.
    image_z: paraxial focus (last vertex z + bfl); the detector may sit elsewhere
        (`Prescription.image_z`).
    wavelength_um: the wavelength these were computed at.
    """

    efl: float
    bfl: float
    epd: float
    f_number: float
    entrance_pupil_z: float
    exit_pupil_z: float
    exit_pupil_diameter: float
    stop_semi_diameter: float
    image_z: float
    wavelength_um: float
    angular_magnification: float | None = None  # an afocal system's (module docstring); None if focal
    image_index: float = 1.0       # n' of the image medium (water, oil: an immersion objective)
    image_na: float = 0.0          # paraxial image-space NA, n' u' of the axial marginal ray (n' sin u' paraxially)

    @property
    def image_space_focal_length(self) -> float:
        """n' · efl: the rear focal length measured in the image medium (OpticStudio's "in image space",
        optiland's f2); efl itself is referred to air (1 / power), as OpticStudio's "in air" EFL."""
        return self.image_index * self.efl

    @property
    def afocal(self) -> bool:
        return self.angular_magnification is not None


def indices(prescription: Prescription, wavelength_um: float, signed: bool = False) -> np.ndarray:
    """Refractive index of every medium: (S+1,), [0] in front of surface 1, [i+1] after surface i.

    signed=True gives the paraxial signed indices (negative while light travels -z).
    """
    out = [1.0]
    for s, sign in zip(prescription.surfaces, prescription.travel):
        out.append(float(refractive_index(s.material, wavelength_um)) * (sign if signed else 1))
    return np.array(out)


def surface_matrices(prescription: Prescription, wavelength_um: float) -> tuple[list, list]:
    """Refraction matrices R[i] (S) and transfer matrices T[i] (S) acting on (y, n u)."""
    n = indices(prescription, wavelength_um, signed=True)
    refr, trans = [], []
    for i, s in enumerate(prescription.surfaces):
        phi = (n[i + 1] - n[i]) * s.vertex_curvature
        refr.append(np.array([[1.0, 0.0], [-phi, 1.0]]))
        trans.append(np.array([[1.0, s.thickness / n[i + 1]], [0.0, 1.0]]))
    return refr, trans


def _chain(refr, trans, first: int, last: int, include_last_refraction: bool = True) -> np.ndarray:
    """Matrix from just before surface `first` to just after surface `last` (vertex planes)."""
    m = np.eye(2)
    for i in range(first, last + 1):
        if i > first:
            m = trans[i - 1] @ m
        if i < last or include_last_refraction:
            m = refr[i] @ m
    return m


def paraxial(prescription: Prescription, wavelength_um: float | None = None) -> Paraxial:
    """First-order properties at `wavelength_um` (default: the primary wavelength)."""
    wl = prescription.primary_wavelength_um if wavelength_um is None else float(wavelength_um)
    refr, trans = surface_matrices(prescription, wl)
    nsurf = len(prescription.surfaces)
    stop = prescription.stop_index
    z_vertex = prescription.vertex_z
    last = nsurf - 1

    n_image = indices(prescription, wl, signed=True)[-1]
    system = _chain(refr, trans, 0, last)  # before surface 1 -> after last surface
    a, c = system[0, 0], system[1, 0]
    power = -c
    surface_powers = sum(abs(r[1, 0]) for r in refr)
    afocal = abs(power) < AFOCAL_POWER_RATIO * surface_powers
    efl = 1.0 / _nonzero(power)
    bfl = -a * n_image / _nonzero(c)  # signed z distance, negative while light runs -z

    # Entrance pupil: object-space ray (y1, u1) at surface 1 that crosses the stop's axis point.
    # y_stop = A y1 + B u1 = 0, and the ray meets the axis at z = -y1/u1 = B/A.
    front = _chain(refr, trans, 0, stop, include_last_refraction=False)
    entrance_pupil_z = _finite(front[0, 1] / _nonzero(front[0, 0]))  # telecentric: far away
    kind, value = prescription.aperture.kind, float(prescription.aperture.value)
    if kind == "epd":
        epd = value
    elif kind == "fno":
        epd = abs(efl) / value
    else:  # object-space numerical aperture: the marginal ray's slope is fixed, the pupil may be far away
        epd = _finite(2.0 * math.tan(math.asin(value)) * abs(prescription.object_distance + entrance_pupil_z))
    f_number = abs(efl) / epd
    y1, u1 = marginal_start(prescription, epd, entrance_pupil_z)
    stop_semi = abs(front[0, 0] * y1 + front[0, 1] * u1)
    y_out, nu_out = system @ np.array([y1, u1])   # the marginal ray after the last surface: (y, n' u')
    if prescription.finite_object:
        # the paraxial image of the axial object point, from the last vertex
        bfl = -y_out * n_image / _nonzero(nu_out)

    # Exit pupil: from the stop's vertex plane (medium before the stop's refraction) to image space.
    back = _chain(refr, trans, stop, last)
    exit_pupil_z = z_vertex[last] - back[0, 1] * n_image / _nonzero(back[1, 1])
    # Lateral magnification of the stop's image: det / D, and det = 1 in (y, n u) coordinates.
    magnification = 1.0 / _nonzero(back[1, 1])
    exit_pupil_diameter = abs(2.0 * stop_semi * magnification)

    return Paraxial(
        efl=float(efl), bfl=float(bfl), epd=float(epd), f_number=float(f_number),
        entrance_pupil_z=float(entrance_pupil_z), exit_pupil_z=float(exit_pupil_z),
        exit_pupil_diameter=_finite(exit_pupil_diameter), stop_semi_diameter=float(stop_semi),
        image_z=float(z_vertex[last] + bfl), wavelength_um=wl,
        angular_magnification=float(system[1, 1] / n_image) if afocal else None,
        image_index=float(abs(n_image)), image_na=float(abs(nu_out)),
    )


def marginal_heights(prescription: Prescription, wavelength_um: float | None = None) -> np.ndarray:
    """Paraxial marginal-ray heights (S,) at every surface for the full entrance pupil."""
    wl = prescription.primary_wavelength_um if wavelength_um is None else float(wavelength_um)
    refr, trans = surface_matrices(prescription, wl)
    par = paraxial(prescription, wl)
    v = np.array(marginal_start(prescription, par.epd, par.entrance_pupil_z))
    out = []
    for i in range(len(prescription.surfaces)):
        if i > 0:
            v = trans[i - 1] @ v
        out.append(v[0])
        v = refr[i] @ v
    return np.array(out)


def marginal_start(prescription: Prescription, epd: float, entrance_pupil_z: float) -> tuple[float, float]:
    """(y, n u) of the paraxial marginal ray on surface 1's vertex plane (object space is air).

    At infinity the ray is parallel at height epd/2; from a finite object it leaves
    the axial object point towards the rim of the entrance pupil.
    """
    if not prescription.finite_object:
        return epd / 2.0, 0.0
    if prescription.aperture.kind == "object_na":
        u = math.tan(math.asin(float(prescription.aperture.value)))
    else:
        u = (epd / 2.0) / _nonzero(prescription.object_distance + entrance_pupil_z)
    return u * prescription.object_distance, u


def object_height_at(prescription: Prescription, angle_deg: float) -> float:
    """Height (mm) on a finite object's plane seen `angle_deg` off the axis from the paraxial entrance
    pupil's centre, as a file's field angles are (OpticStudio's convention). An entrance pupil at infinity
    or behind the object (telecentric object space) sees every height at 0°: the angle beyond the largest
    field is then added to the field's edge seen from surface 1's vertex."""
    p = prescription
    d = p.object_distance + paraxial(p).entrance_pupil_z
    if 0.0 < d < FAR_PUPIL_DISTANCES * p.object_distance:
        return d * math.tan(math.radians(angle_deg))
    edge = max((abs(h) for h in p.object_heights_mm), default=0.0)
    seen = math.atan2(edge, p.object_distance) + math.radians(angle_deg - p.max_field_deg)
    return p.object_distance * math.tan(min(seen, math.radians(MAX_OBJECT_ANGLE_DEG)))


def _nonzero(x: float) -> float:
    """Keep an afocal system's zero power from turning into a division error: tiny, same sign."""
    return x if abs(x) > _TINY else math.copysign(_TINY, x if x != 0 else 1.0)


def _finite(x: float) -> float:
    return float(x) if math.isfinite(x) else 1e300


__all__ = ["Paraxial", "paraxial", "marginal_heights", "marginal_start", "indices", "surface_matrices",
           "object_height_at"]
