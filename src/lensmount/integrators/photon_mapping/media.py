"""Radiance across a refractive boundary: why a hit point inside glass is worth n_det²/n².

Radiance divided by n² is what travels unchanged through a lossless interface
(L_air = L_glass / n² with perfect AR). A view-map hit point made by a backward ray
that reached a lens edge or bevel from INSIDE the glass estimates the glass-side
radiance there (photons deposit flux per area, the BSDF turns it into radiance in
the glass); a detector in air receives that radiance divided by n². A detector in
optical contact with a medium of index n_det (an immersion objective's specimen plane,
`Detector.medium_index`) receives n_det² times the air-side radiance: its backward
samples are drawn over the hemisphere in that medium. Hits on mechanical parts, and on
lens faces seen from the air, keep a factor n_det² (1 in air).
"""

from __future__ import annotations

import numpy as np


def detector_radiance_factor(scene, direction: np.ndarray, tag: np.ndarray, prim: np.ndarray | None,
                             wavelength: np.ndarray) -> np.ndarray:
    """(H,) n_det² / n² for hits made from inside a lens part's glass, else n_det² (n_det: the index of
    the medium in front of the detector, 1 in air).

    direction : (H, 3) travel direction of the backward ray arriving at the hit
    tag, prim : (H,) mesh tag and triangle of the hit (prim None: no mesh, factor 1)
    wavelength : (H,) wavelength index
    """
    n_det2 = scene.detector.medium_index_at(wavelength) ** 2
    if prim is None or len(tag) == 0:
        return n_det2
    n = scene.solid_index_of_tag[tag, wavelength]
    glass = n != 1.0
    if not glass.any():
        return n_det2
    v = scene.mesh.vertices
    tri = scene.mesh.triangles[np.asarray(prim, np.int64)]
    outward = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])  # CCW seen from outside
    leaving_solid = np.einsum("ij,ij->i", direction, outward) > 0.0  # the ray was inside the solid
    return n_det2 * np.where(glass & leaving_solid, 1.0 / (n * n), 1.0)
