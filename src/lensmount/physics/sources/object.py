"""An object at a finite distance: an isotropic point or a Lambertian disc (`ObjectSource`)."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from lensmount.errors import InputError
from lensmount.physics.rays import RayBatch
from lensmount.physics.sources.base import SOURCES, Placement, SourceParams


# Midpoint quadrature of the entrance pupil (rings × azimuths) and of a disc source, for the
# flux an object source sends into the pupil: smooth integrands, ~1e-5 relative.
_PUPIL_RINGS, _PUPIL_AZIMUTHS = 48, 96
_DISC_RINGS, _DISC_AZIMUTHS = 12, 24


def _disc_points(centre, radius: float, rings: int, azimuths: int, normal_z: bool = True):
    """Midpoint-rule nodes (M, 3) and areas (M,) of a disc normal to z (one node for radius 0)."""
    c = np.asarray(centre, np.float64)
    if radius <= 0.0:
        return c[None, :], np.ones(1)
    edges = radius * np.sqrt(np.arange(rings + 1) / rings)  # equal-area rings
    r = np.sqrt(0.5 * (edges[1:] ** 2 + edges[:-1] ** 2))
    phi = 2.0 * np.pi * (np.arange(azimuths) + 0.5) / azimuths
    rr, pp = np.meshgrid(r, phi, indexing="ij")
    pts = np.column_stack([c[0] + (rr * np.cos(pp)).ravel(), c[1] + (rr * np.sin(pp)).ravel(),
                           np.full(rr.size, c[2])])
    return pts, np.full(rr.size, math.pi * radius**2 / rr.size)


@dataclass(frozen=True)
class ObjectSource:
    """An object at a finite distance: an isotropic point (radius 0) or a Lambertian disc facing
    +z (radius > 0), centred at `centre` (mm, assembly frame; usually on the lens's object plane).

    Units (what makes the stray fraction "of the light the lens accepts"): photons carry flux in
    units of E_ref·mm², where E_ref is the mean irradiance the source makes over the paraxial
    entrance pupil (disc of radius `pupil_radius` at z = `pupil_z`): E_ref · A_EP is the flux it
    sends into the pupil, Φ_EP = I · Ω_EP (point of intensity I; Ω_EP the solid angle of the cone of
    lines from the point through the pupil, real or virtual) or L · G_EP (disc of radiance L; G_EP
    its étendue into the pupil). So `entering_fraction` is 1 and the loop's aperture flux A_EP ·
    1 is Φ_EP: stray fraction = detector flux / flux into the entrance pupil, and images read
    E / E_ref, as E / E_sun for the sun.

    Photons start on the source (uniform over the disc) and leave uniformly inside the cone from
    their start that just holds the sphere around the front opening (`aim_z`, `aim_radius`); a
    point inside that sphere emits over the +z hemisphere. Light the cone leaves out cannot enter
    the front opening.
    """

    at_infinity: ClassVar[bool] = False
    centre: tuple[float, float, float]
    radius: float
    aim_z: float
    aim_radius: float
    pupil_z: float
    pupil_radius: float
    wavelength_weights: tuple[float, ...] = (1.0,)

    @property
    def entering_fraction(self) -> float:
        return 1.0

    @property
    def off_axis_deg(self) -> float:
        """Angle of the source's centre off the axis seen from the entrance pupil's centre (the
        object-space field angle of its chief ray), degrees."""
        x, y, z = self.centre
        return math.degrees(math.atan2(math.hypot(x, y), max(self.pupil_z - z, 0.0)))

    @property
    def half_angle_rad(self) -> float:
        """Angular radius of the disc seen from the entrance pupil's centre (0 for a point)."""
        return math.atan2(self.radius, max(self.pupil_z - self.centre[2], 0.0))

    @property
    def no_light_enters(self) -> str | None:
        return None

    @functools.cached_property
    def pupil_etendue(self) -> float:
        """Ω_EP (point, sr) or G_EP / A_source (disc, sr): what the source sends into the entrance
        pupil per unit intensity, resp. per unit radiance and source area."""
        pupil, dA = _disc_points((0.0, 0.0, self.pupil_z), self.pupil_radius, _PUPIL_RINGS, _PUPIL_AZIMUTHS)
        src, dS = _disc_points(self.centre, self.radius, _DISC_RINGS, _DISC_AZIMUTHS)
        v = pupil[None, :, :] - src[:, None, :]
        r2 = np.maximum(np.einsum("ijk,ijk->ij", v, v), 1e-300)
        cos_p = np.abs(v[..., 2]) / np.sqrt(r2)  # lines through a virtual pupil count as well
        lambert = cos_p if self.radius > 0.0 else 1.0  # a disc facing the pupil plane: the same cosine
        g = (lambert * cos_p / r2 * dA[None, :]).sum(axis=1)
        return float((g * dS).sum() / dS.sum())

    def emit(self, n: int, rng) -> tuple[RayBatch, float]:
        """n photons: (RayBatch with weight = flux per photon in E_ref·mm², mean flux per photon)."""
        u = rng.random((n, 5))
        origin = np.tile(np.asarray(self.centre, np.float64), (n, 1))
        if self.radius > 0.0:
            r = self.radius * np.sqrt(u[:, 0])
            origin[:, 0] += r * np.cos(2.0 * np.pi * u[:, 1])
            origin[:, 1] += r * np.sin(2.0 * np.pi * u[:, 1])
        to_aim = np.array([0.0, 0.0, self.aim_z]) - origin
        dist = np.linalg.norm(to_aim, axis=1)
        outside = dist > self.aim_radius
        axis = np.where(outside[:, None], to_aim / np.where(outside, dist, 1.0)[:, None], [0.0, 0.0, 1.0])
        cos_beta = np.where(outside, np.sqrt(np.maximum(0.0, 1.0 - (self.aim_radius / np.maximum(dist, 1e-300)) ** 2)),
                            0.0)
        cos_t = 1.0 - u[:, 2] * (1.0 - cos_beta)
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        psi = 2.0 * np.pi * u[:, 3]
        helper = np.where((np.abs(axis[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        e1 = np.cross(axis, helper)
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 = np.cross(axis, e1)
        direction = (cos_t[:, None] * axis + (sin_t * np.cos(psi))[:, None] * e1
                     + (sin_t * np.sin(psi))[:, None] * e2)
        solid_angle = 2.0 * np.pi * (1.0 - cos_beta)  # of each photon's cone (pdf 1 / solid_angle)
        lambert = np.maximum(direction[:, 2], 0.0) if self.radius > 0.0 else 1.0
        area = math.pi * self.pupil_radius**2
        weight = area * lambert * solid_angle / (max(n, 1) * self.pupil_etendue)
        w = np.asarray(self.wavelength_weights, np.float64)
        wavelength = rng.choice(len(w), size=n, p=w / w.sum()) if len(w) > 1 else np.zeros(n, np.int32)
        return RayBatch.make(origin, direction, weight=weight, wavelength=wavelength), float(weight.mean()) if n else 0.0


class PointParams(SourceParams):
    at_infinity: ClassVar[bool] = False
    type: Literal["point"]
    height_mm: float = Field(default=0.0, ge=0.0)
    azimuth_deg: float = 90.0
    z_mm: float | None = None


class DiscParams(PointParams):
    type: Literal["disc"]  # type: ignore[assignment]
    radius_mm: float = Field(gt=0.0)


def _object(p: PointParams, at: Placement, radius: float) -> ObjectSource:
    """Centred at height_mm toward azimuth_deg on the plane z_mm (default: the lens's object plane)."""
    z = p.z_mm if p.z_mm is not None else at.object_z
    if z is None:
        raise InputError(f"a {p.type} source needs a plane: the lens has its object at infinity", field="source.z_mm",
                         valid="z_mm (mm, surface 1's vertex at 0, the object side negative), or a lens with a "
                               "finite object distance")
    if z >= 0.0:
        raise InputError(f"the {p.type} source at z = {z:g} mm is not in front of surface 1", field="source.z_mm",
                         valid="a plane in front of the lens, z_mm < 0")
    pupil_z, pupil_radius = at.pupil()
    a = math.radians(p.azimuth_deg)
    centre = (p.height_mm * math.cos(a), p.height_mm * math.sin(a), float(z))
    return ObjectSource(centre, radius, float(at.opening_z), float(at.opening_radius) * 1.02 + 1e-3,
                        float(pupil_z), float(pupil_radius), at.wavelength_weights)


@SOURCES.register("point", PointParams)
def _point(p: PointParams, at: Placement) -> ObjectSource:
    return _object(p, at, 0.0)


@SOURCES.register("disc", DiscParams)
def _disc(p: DiscParams, at: Placement) -> ObjectSource:
    return _object(p, at, float(p.radius_mm))


__all__ = ["ObjectSource", "PointParams", "DiscParams"]
