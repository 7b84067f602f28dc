"""Absorber: a perfectly black surface. It reflects nothing; paths end on it.

| parameter | meaning |
|-----------|---------|
| (none)    |         |

Scene file: ``"*" = "absorber"`` or ``{ model = "absorber" }``.
"""

from __future__ import annotations

import numpy as np

from lensmount.physics.bsdf.base import BSDF, BSDFS, BSDFParams, as_rows


class AbsorberParams(BSDFParams):
    """No parameters."""


@BSDFS.register("absorber", AbsorberParams)
class Absorber(BSDF):
    """f = 0 everywhere; `sample` returns dead lanes (weight 0, pdf 0, wo = n)."""

    name = "absorber"
    tis = 0.0
    weight_bound = 0.0
    is_black = True

    def __init__(self, params: AbsorberParams | None = None):
        pass

    def eval(self, wi, wo, n):
        return np.zeros(len(as_rows(wi)))

    def sample(self, wi, n, u):
        n = as_rows(n, "n")
        zeros = np.zeros(len(n))
        return n.copy(), zeros, zeros.copy()

    def pdf(self, wi, wo, n):
        return np.zeros(len(as_rows(wi)))

    def albedo(self, wi, n):
        return np.zeros(len(as_rows(wi)))
