"""Snell's law and mirror reflection for batches of unit directions: the one numpy copy, shared by
the sequential trace (optics.realrays), the tracer's glass interfaces and the ghost routes
(physics.interfaces). The compiled walk has its own scalar copy (trace.kernels), checked against
this one in tests/trace.
"""

from __future__ import annotations

import numpy as np


def refract(d: np.ndarray, n: np.ndarray, eta: np.ndarray):
    """Vector Snell's law.

    d : (N, 3) unit incident directions; n : (N, 3) unit normals (either orientation);
    eta : (N,) n1 / n2. Returns (t (N, 3) unit refracted directions, tir (N,) bool,
    cos_i (N,) >= 0, cos_t (N,) >= 0). Where tir is true, t is the mirror reflection
    (total internal reflection: what the light does there).
    """
    cos_dn = np.einsum("ij,ij->i", d, n)
    m = n * np.where(cos_dn >= 0.0, 1.0, -1.0)[:, None]  # normal along the travel direction
    cos_i = np.abs(cos_dn)
    sin2_t = eta * eta * np.maximum(0.0, 1.0 - cos_i * cos_i)
    tir = sin2_t > 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    t = eta[:, None] * d + (cos_t - eta * cos_i)[:, None] * m
    t = np.where(tir[:, None], reflect(d, n), t)
    t = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    return t, tir, cos_i, np.where(tir, 0.0, cos_t)


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror reflection d − 2 (d·n) n of directions d (N, 3) about unit normals n (N, 3), either sign."""
    return d - 2.0 * np.einsum("ij,ij->i", d, n)[:, None] * n


__all__ = ["refract", "reflect"]
