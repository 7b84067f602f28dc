"""Who counts the light a glossy finish scatters: the photons count its lobe's core, the gather the rest.

`bidirectional.gather_cores` sets the core per finish (direction cosines around the mirror direction);
the walk leaves to the gather a photon whose last scatter left outside it, the gather and the
connections count only what lies outside it: one function, so the three agree to the bit.
"""

from __future__ import annotations

import numpy as np


def outside_core(wi: np.ndarray, wo: np.ndarray, n: np.ndarray, core) -> np.ndarray:
    """(N,) bool: wo lies at least `core` from the mirror direction of wi, in direction cosines.

    The tangential part of the mirror direction is −t(wi), so the distance is |t(wo) + t(wi)|
    (t: the part in the surface plane); symmetric in wi and wo, like the BSDF."""
    t = wi + wo
    t = t - np.einsum("ij,ij->i", t, n)[:, None] * n
    return np.einsum("ij,ij->i", t, t) >= core * core


__all__ = ["outside_core"]
