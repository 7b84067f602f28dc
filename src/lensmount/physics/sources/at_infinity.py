"""Sources at infinity: the sun (a 0.53° disc, optionally limb-darkened) and a collimated point source.

Flux bookkeeping (what makes results independent of the emission disc): photons start
uniformly on a disc of area A_S normal to the central direction, placed outside the
assembly and covering its front opening; a source of irradiance E_sun sends E_sun · A_S
through that disc, so each of N photons carries Φ = A_S / N in units of E_sun · mm². Any
larger disc gives the same detector irradiance (more photons simply miss).

Sun directions: uniform over the solar disc of angular radius α (cos-weighting across
0.27° is 1 − 1e-5, ignored) or, with `limb_darkening`, weighted by the standard linear law
I(μ)/I(1) = 1 − u (1 − μ), u = 0.6, μ = cos of the angle from the disc centre seen on the sun.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from lensmount.physics.rays import RayBatch
from lensmount.physics.sources.base import (
    SOURCES, SUN_ANGULAR_DIAMETER_DEG, EmissionDisc, Placement, SourceParams, disc_radius_fraction, emission_disc,
    entering_fraction, no_light_enters_reason, orthonormal_basis, source_direction)


class _ParallelBeam:
    """What the sun and a collimated source share: a beam from (off_axis_deg, azimuth_deg) whose
    photons start on `disc`, inside a cone of half-angle `half_angle_rad`."""

    at_infinity: ClassVar[bool] = True

    @property
    def direction(self) -> np.ndarray:
        return source_direction(self.off_axis_deg, self.azimuth_deg)

    @property
    def entering_fraction(self) -> float:
        """Irradiance through the entrance plane / E_sun (see `entering_fraction`)."""
        return entering_fraction(self.off_axis_deg, self.half_angle_rad, self.limb_darkening)

    @property
    def no_light_enters(self) -> str | None:
        """The reason no light enters the front opening, for the run summary; None when some does."""
        return no_light_enters_reason(self.off_axis_deg, self.half_angle_rad)

    def emit(self, n: int, rng: np.random.Generator) -> tuple[RayBatch, float]:
        """n photons: (RayBatch with weight = flux per photon, flux per photon [E_sun·mm²])."""
        return _emit(self, n, rng, self.half_angle_rad, self.limb_darkening)


@dataclass(frozen=True)
class SunSource(_ParallelBeam):
    """The sun: angular disc of `angular_diameter_deg`, at (off_axis_deg, azimuth_deg).

    wavelength_weights (W,) are the source's relative spectral weights over the scene's
    wavelengths (photon wavelengths are drawn in proportion).
    """

    off_axis_deg: float
    azimuth_deg: float
    disc: EmissionDisc
    angular_diameter_deg: float = SUN_ANGULAR_DIAMETER_DEG
    limb_darkening: bool = False
    wavelength_weights: tuple[float, ...] = (1.0,)

    @property
    def half_angle_rad(self) -> float:
        return 0.5 * math.radians(self.angular_diameter_deg)


@dataclass(frozen=True)
class CollimatedSource(_ParallelBeam):
    """A point source at infinity (a perfectly collimated beam), for PST sweeps."""

    limb_darkening: ClassVar[bool] = False  # a point has no disc
    half_angle_rad: ClassVar[float] = 0.0
    off_axis_deg: float
    azimuth_deg: float
    disc: EmissionDisc
    wavelength_weights: tuple[float, ...] = (1.0,)


def _emit(source, n: int, rng: np.random.Generator, alpha: float, limb: bool) -> tuple[RayBatch, float]:
    d0 = source.direction
    e1, e2 = orthonormal_basis(d0)
    u = rng.random((n, 4))
    # Position: uniform on the disc.
    r = source.disc.radius * np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    origin = (np.asarray(source.disc.centre)[None, :] + (r * np.cos(phi))[:, None] * e1
              + (r * np.sin(phi))[:, None] * e2)
    # Direction: inside the source's cone of half-angle alpha.
    if alpha > 0.0:
        rho = disc_radius_fraction(u[:, 2], limb) * alpha  # small angle: uniform disc in angle space
        psi = 2.0 * np.pi * u[:, 3]
        direction = (np.cos(rho)[:, None] * d0 + (np.sin(rho) * np.cos(psi))[:, None] * e1
                     + (np.sin(rho) * np.sin(psi))[:, None] * e2)
    else:
        direction = np.broadcast_to(d0, (n, 3)).copy()
    w = np.asarray(source.wavelength_weights, np.float64)
    wavelength = rng.choice(len(w), size=n, p=w / w.sum()) if len(w) > 1 else np.zeros(n, np.int32)
    flux = source.disc.area / max(n, 1)
    return RayBatch.make(origin, direction, weight=np.full(n, flux), wavelength=wavelength), flux



class _AtInfinity(SourceParams):
    at_infinity: ClassVar[bool] = True
    off_axis_deg: float = Field(ge=0.0, le=180.0)
    azimuth_deg: float = 90.0


class SunParams(_AtInfinity):
    type: Literal["sun"] = "sun"
    angular_diameter_deg: float = Field(default=SUN_ANGULAR_DIAMETER_DEG, ge=0.0, le=10.0)
    limb_darkening: bool = False


class CollimatedParams(_AtInfinity):
    type: Literal["collimated"]


@SOURCES.register("sun", SunParams)
def _sun(p: SunParams, at: Placement) -> SunSource:
    half = 0.5 * math.radians(p.angular_diameter_deg)
    disc = emission_disc(source_direction(p.off_axis_deg, p.azimuth_deg), at.opening_z, at.opening_radius,
                         at.clear_distance, half)
    return SunSource(p.off_axis_deg, p.azimuth_deg, disc, p.angular_diameter_deg, p.limb_darkening,
                     at.wavelength_weights)


@SOURCES.register("collimated", CollimatedParams)
def _collimated(p: CollimatedParams, at: Placement) -> CollimatedSource:
    disc = emission_disc(source_direction(p.off_axis_deg, p.azimuth_deg), at.opening_z, at.opening_radius,
                         at.clear_distance)
    return CollimatedSource(p.off_axis_deg, p.azimuth_deg, disc, at.wavelength_weights)


__all__ = ["SunSource", "CollimatedSource", "SunParams", "CollimatedParams"]
