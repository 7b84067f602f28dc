"""A source kind added the way docs/architecture.md says ("Where to add a source"): this file, which
registers itself in `SOURCES`, and its line in the plug-in package's entry points; nothing of lensmount touched.

A laser beam: a collimated beam of radius `beam_radius_mm` whose axis passes through the centre
of the front opening, at (off_axis_deg, azimuth_deg). Irradiance 1 inside the beam, so a photon
carries π r² / N (units E·mm²), like the sun's photons carry A_disc / N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from lensmount.physics.rays import RayBatch
from lensmount.physics.sources import (SOURCES, EmissionDisc, Placement, SourceParams, emission_disc,
                                       orthonormal_basis, source_direction)


class BeamParams(SourceParams):
    at_infinity: ClassVar[bool] = True
    type: Literal["beam"]
    off_axis_deg: float = Field(ge=0.0, lt=90.0)
    azimuth_deg: float = 90.0
    beam_radius_mm: float = Field(gt=0.0)


@dataclass(frozen=True)
class BeamSource:
    at_infinity: ClassVar[bool] = True
    limb_darkening: ClassVar[bool] = False
    off_axis_deg: float
    azimuth_deg: float
    disc: EmissionDisc  # the beam's own cross-section, set back outside the assembly
    wavelength_weights: tuple[float, ...] = (1.0,)

    @property
    def direction(self) -> np.ndarray:
        return source_direction(self.off_axis_deg, self.azimuth_deg)

    @property
    def half_angle_rad(self) -> float:
        return 0.0

    @property
    def entering_fraction(self) -> float:
        return math.cos(math.radians(self.off_axis_deg))

    @property
    def no_light_enters(self) -> str | None:
        return None

    def emit(self, n: int, rng: np.random.Generator) -> tuple[RayBatch, float]:
        u = rng.random((n, 2))
        r = self.disc.radius * np.sqrt(u[:, 0])
        phi = 2.0 * np.pi * u[:, 1]
        e1, e2 = orthonormal_basis(self.direction)
        origin = (np.asarray(self.disc.centre)[None, :] + (r * np.cos(phi))[:, None] * e1
                  + (r * np.sin(phi))[:, None] * e2)
        flux = self.disc.area / max(n, 1)
        direction = np.broadcast_to(self.direction, (n, 3)).copy()
        return RayBatch.make(origin, direction, weight=np.full(n, flux), wavelength=np.zeros(n, np.int32)), flux


@SOURCES.register("beam", BeamParams)
def build_beam(p: BeamParams, at: Placement) -> BeamSource:
    """A collimated beam of radius `beam_radius_mm` through the centre of the front opening."""
    d = source_direction(p.off_axis_deg, p.azimuth_deg)
    around_opening = emission_disc(d, at.opening_z, at.opening_radius, at.clear_distance)
    return BeamSource(p.off_axis_deg, p.azimuth_deg, EmissionDisc(around_opening.centre, p.beam_radius_mm),
                      at.wavelength_weights)

