"""The detector: a rectangle in the image plane, centred on the axis, facing the lens (−z).

Pixels are row-major (ny, nx), flat index = iy · nx + ix, row 0 at the −y edge and column 0
at the −x edge (the `PassEstimate` convention). Only light arriving from the lens side
(direction z > 0) is recorded; the back of the detector is opaque and records nothing.

Irradiance bookkeeping: photons carry flux in units of E_sun · mm², so a pixel's value
Σ Φ / A_pixel is the irradiance normalised by the source irradiance (E/E_sun).

Optional spectral weighting: `spectral_weight` (W,) multiplies every deposit of wavelength
index k by spectral_weight[k] (a detector's relative spectral response); None = 1.

The medium in front of it: `medium_index` (W,) is the index of the medium the detector is in
optical contact with (an immersion objective's water or oil, `Prescription.image_medium`); () is air.
Flux per area (what photons deposit) is the same in any medium; radiance is not: L / n² is what
passes an interface unchanged, so a backward estimate of E = ∫ L cos θ dω sampled in the medium
takes n² times the radiance seen in air (integrators/photon_mapping/media.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Detector:
    """width, height in mm; nx, ny pixels; z of the image plane (mm, assembly frame)."""

    width: float
    height: float
    nx: int
    ny: int
    z: float
    spectral_weight: tuple[float, ...] | None = None
    medium_index: tuple[float, ...] = ()

    def medium_index_at(self, wavelength: np.ndarray) -> np.ndarray:
        """(H,) index of the medium in front of the detector at wavelength indices (H,): 1 in air."""
        wavelength = np.asarray(wavelength, np.int64)
        if not self.medium_index:
            return np.ones(len(wavelength))
        return np.asarray(self.medium_index, np.float64)[wavelength]

    @property
    def pixel_area(self) -> float:
        """Area of one pixel, mm²."""
        return (self.width / self.nx) * (self.height / self.ny)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.ny, self.nx)

    def intersect(self, origin: np.ndarray, direction: np.ndarray, t_min: float):
        """Ray parameter of the hit with the detector rectangle, (N,), inf where it misses.

        Both faces block light (`front` (N,) says which side was hit: True = from the lens).
        """
        dz = direction[:, 2]
        moving = np.abs(dz) > 1e-300
        t = np.where(moving, (self.z - origin[:, 2]) / np.where(moving, dz, 1.0), np.inf)
        p = origin + np.where(np.isfinite(t), t, 0.0)[:, None] * direction
        inside = (np.abs(p[:, 0]) <= 0.5 * self.width) & (np.abs(p[:, 1]) <= 0.5 * self.height)
        t = np.where(moving & inside & (t > t_min), t, np.inf)
        return t, dz > 0.0

    def pixel_of(self, points: np.ndarray) -> np.ndarray:
        """(N,) flat pixel index of points (N, 3) on the plane, −1 outside the detector."""
        fx = (points[:, 0] + 0.5 * self.width) * (self.nx / self.width)
        fy = (points[:, 1] + 0.5 * self.height) * (self.ny / self.height)
        ok = np.isfinite(fx) & np.isfinite(fy) & (fx >= 0) & (fy >= 0) & (fx <= self.nx) & (fy <= self.ny)
        # A point exactly on the +x or +y edge belongs to the last pixel, not outside.
        ix = np.minimum(np.floor(np.where(ok, fx, 0.0)), self.nx - 1).astype(np.int64)
        iy = np.minimum(np.floor(np.where(ok, fy, 0.0)), self.ny - 1).astype(np.int64)
        return np.where(ok, iy * self.nx + ix, -1)

    def sample_points(self, pixel: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(N, 3) points uniform in flat pixels (N,), from uniforms u (N, 2)."""
        return self.sample_blocks(pixel, 1, u)[0]

    def blocks(self, pitch: int) -> tuple[int, int]:
        """(across, up) blocks of `pitch` × `pitch` pixels that tile the detector (the last ones cut by its edges)."""
        return -(-self.nx // int(pitch)), -(-self.ny // int(pitch))

    def sample_blocks(self, block: np.ndarray, pitch: int, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 3) points uniform in flat blocks (N,) of `pitch` × `pitch` pixels (`blocks`; pitch 1: pixels), from
        uniforms u (N, 2); the flat pixel each lies in; each block's size in pixels (fewer where the detector's
        edges cut it)."""
        by, bx = np.divmod(np.asarray(block, np.int64), self.blocks(pitch)[0])
        ix0, iy0 = bx * pitch, by * pitch
        wx, wy = np.minimum(pitch, self.nx - ix0), np.minimum(pitch, self.ny - iy0)
        x = -0.5 * self.width + (ix0 + u[:, 0] * wx) * (self.width / self.nx)
        y = -0.5 * self.height + (iy0 + u[:, 1] * wy) * (self.height / self.ny)
        ix = ix0 + np.minimum((u[:, 0] * wx).astype(np.int64), wx - 1)
        iy = iy0 + np.minimum((u[:, 1] * wy).astype(np.int64), wy - 1)
        points = np.column_stack([x, y, np.full(len(x), float(self.z))])
        return points, iy * self.nx + ix, (wx * wy).astype(np.float64)

    def deposit(self, points: np.ndarray, flux: np.ndarray, wavelength: np.ndarray | None = None) -> np.ndarray:
        """Irradiance image (ny, nx), E/E_sun, from photons of flux (N,) [E_sun·mm²] landing at points."""
        pixel = self.pixel_of(points)
        value = np.where(np.isfinite(flux), flux, 0.0)
        if self.spectral_weight is not None and wavelength is not None:
            value = value * np.asarray(self.spectral_weight, np.float64)[np.asarray(wavelength, np.int64)]
        ok = pixel >= 0
        img = np.bincount(pixel[ok], weights=value[ok], minlength=self.nx * self.ny)
        return (img / self.pixel_area).reshape(self.ny, self.nx)


__all__ = ["Detector"]
