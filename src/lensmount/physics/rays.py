"""Ray batches as structure-of-arrays with an alive mask (no per-ray Python)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


@dataclass
class RayBatch:
    """N rays.

    origin : (N, 3) float64, mm
    direction : (N, 3) float64, unit vectors
    weight : (N,) float64, throughput (photons: flux in units of E_sun·mm²; backward rays: importance)
    wavelength : (N,) int32 index into the scene's wavelength table
    alive : (N,) bool; dead lanes keep their values but are ignored
    id : (N,) int64 identity carried through (photon number, or pixel index for backward rays)
    """

    origin: np.ndarray
    direction: np.ndarray
    weight: np.ndarray
    wavelength: np.ndarray
    alive: np.ndarray
    id: np.ndarray

    @classmethod
    def make(cls, origin, direction, weight=None, wavelength=None, ids=None) -> "RayBatch":
        origin = np.ascontiguousarray(origin, dtype=np.float64).reshape(-1, 3)
        n = len(origin)
        d = np.ascontiguousarray(direction, dtype=np.float64).reshape(-1, 3)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        return cls(
            origin=origin,
            direction=d,
            weight=np.ones(n) if weight is None else np.asarray(weight, dtype=np.float64).copy(),
            wavelength=np.zeros(n, np.int32) if wavelength is None else np.asarray(wavelength, np.int32).copy(),
            alive=np.ones(n, bool),
            id=np.arange(n, dtype=np.int64) if ids is None else np.asarray(ids, np.int64).copy(),
        )

    def __len__(self) -> int:
        return len(self.weight)

    def subset(self, index) -> "RayBatch":
        """Rays at `index` (bool mask or integer array), copied."""
        return RayBatch(**{f.name: getattr(self, f.name)[index].copy() for f in fields(self)})

    def compact(self) -> "RayBatch":
        """Only the live rays."""
        return self.subset(self.alive)

    @staticmethod
    def concatenate(batches: list["RayBatch"]) -> "RayBatch":
        return RayBatch(**{f.name: np.concatenate([getattr(b, f.name) for b in batches]) for f in fields(RayBatch)})
