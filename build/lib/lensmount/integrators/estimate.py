"""What one pass of any integrator produces: a complete, independent estimate.

Passes are independent by construction (see the estimator reference), so the
run's answer is the mean of the passes and its error bar is their spread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PassEstimate:
    """One pass's estimate of detector irradiance, normalised by the source irradiance E_sun.

    image : (ny, nx) float64, E/E_sun per pixel (dimensionless); row 0 is the detector's -y edge
    per_part : (P, ny, nx) float64, the same split by the part of the last scattering event
    part_names : P names, aligned with `per_part`
    pixel_area_mm2 : area of one pixel
    photons : photons traced in this pass
    lost_flux : flux (E_sun·mm²) of rays ended by the tracer's guards (bounce limit, numerical), for the energy ledger
    """

    image: np.ndarray
    per_part: np.ndarray
    part_names: list[str]
    pixel_area_mm2: float
    photons: int
    lost_flux: float = 0.0

    @property
    def flux(self) -> float:
        """Detector stray flux normalised by E_sun (mm²)."""
        return float(self.image.sum() * self.pixel_area_mm2)

    @property
    def part_flux(self) -> np.ndarray:
        """(P,) flux per part, normalised by E_sun (mm²)."""
        return self.per_part.sum(axis=(1, 2)) * self.pixel_area_mm2
