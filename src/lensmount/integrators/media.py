"""Radiance across a refractive boundary: why a hit point inside glass is worth 1/n².

Radiance divided by n² is what travels unchanged through a lossless interface
(L_air = L_glass / n² with perfect AR). A view-map hit point made by a backward ray
that reached a lens edge or bevel from INSIDE the glass estimates the glass-side
radiance there (photons deposit flux per area, the BSDF turns it into radiance in
the glass); the detector, in air, receives that radiance divided by n². Hits on
mechanical parts, and on lens faces seen from the air, keep a factor 1.
"""

from __future__ import annotations

import numpy as np


def air_radiance_factor(scene, direction: np.ndarray, tag: np.ndarray, prim: np.ndarray | None,
                        wavelength: np.ndarray) -> np.ndarray:
    """(H,) 1/n² for hits made from inside a lens part's glass, else 1.

    direction : (H, 3) travel direction of the backward ray arriving at the hit
    tag, prim : (H,) mesh tag and triangle of the hit (prim None: no mesh, factor 1)
    wavelength : (H,) wavelength index
    """
    if prim is None or len(tag) == 0:
        return np.ones(len(tag))
    n = scene.solid_index_of_tag[tag, wavelength]
    glass = n != 1.0
    if not glass.any():
        return np.ones(len(tag))
    v = scene.mesh.vertices
    tri = scene.mesh.triangles[np.asarray(prim, np.int64)]
    outward = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])  # CCW seen from outside
    leaving_solid = np.einsum("ij,ij->i", direction, outward) > 0.0  # the ray was inside the solid
    return np.where(glass & leaving_solid, 1.0 / (n * n), 1.0)
