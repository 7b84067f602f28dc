"""Specular mirror: all reflected light leaves along the mirror direction of wi.

| parameter     | meaning                         | valid  | default |
|---------------|---------------------------------|--------|---------|
| `reflectance` | R, fraction of flux reflected   | [0, 1] | 1.0     |

Scene file: ``{ model = "mirror", reflectance = 0.9 }``. A delta lobe: `eval`
and `pdf` are 0; `sample` returns wo = 2(n·wi)n − wi with pdf 1 (the discrete
probability of the lobe) and weight R. `tis` and `albedo` are R (the whole
hemispherical reflectance, which for a mirror is all specular).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from lensmount.physics.bsdf.base import BSDF, BSDFS, COS_EPS, BSDFParams, as_rows, dot, mirror, normalize


class MirrorParams(BSDFParams):
    reflectance: float = Field(1.0, ge=0.0, le=1.0)


@BSDFS.register("mirror", MirrorParams)
class Mirror(BSDF):
    """Perfect specular reflector of reflectance R."""

    name = "mirror"
    is_delta = True
    lobe_half_width_deg = 0.0

    def __init__(self, params: MirrorParams):
        self.reflectance = params.reflectance
        self.tis = self.weight_bound = self.reflectance

    @property
    def params(self):
        return {"reflectance": self.reflectance}

    def eval(self, wi, wo, n):
        return np.zeros(len(as_rows(wi)))

    def sample(self, wi, n, u):
        wi, n = as_rows(wi, "wi"), as_rows(n, "n")
        wo = normalize(mirror(wi, n))
        live = dot(wi, n) > COS_EPS
        return wo, np.where(live, self.reflectance, 0.0), np.where(live, 1.0, 0.0)

    def pdf(self, wi, wo, n):
        return np.zeros(len(as_rows(wi)))

    def albedo(self, wi, n):
        wi, n = as_rows(wi, "wi"), as_rows(n, "n")
        return np.where(dot(wi, n) > COS_EPS, self.reflectance, 0.0)
