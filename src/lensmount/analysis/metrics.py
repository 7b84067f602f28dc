"""Figures of merit derived from a run: stray fraction and its error bar.

A run reports detector flux normalised by the source irradiance E_sun (units mm²).
The flux that enters the aperture, in the same units, is the entrance pupil's area
projected along the source direction: π (EPD/2)² cos θ_sun. Their ratio is the
*stray fraction*, the share of the light entering the lens that reaches the detector
as stray light (dimensionless, independent of the sun's brightness).
"""

from __future__ import annotations

import math


def stray_fraction(detector_flux_mm2: float, aperture_flux_mm2: float) -> float:
    """Detector stray flux / flux entering the aperture; 0 when no light enters (sun at 90°)."""
    if not aperture_flux_mm2 > 0 or not math.isfinite(detector_flux_mm2):
        return 0.0
    return detector_flux_mm2 / aperture_flux_mm2


def finite_or_none(x: float) -> float | None:
    """JSON-safe number: a finite float, or None where the value is unknown (e.g. one pass)."""
    x = float(x)
    return x if math.isfinite(x) else None


__all__ = ["stray_fraction", "finite_or_none"]
