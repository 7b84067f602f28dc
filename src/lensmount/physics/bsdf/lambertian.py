"""Lambertian (perfectly diffuse) reflector: f = ρ/π, the same radiance in every direction.

| parameter     | meaning                                             | valid  |
|---------------|-----------------------------------------------------|--------|
| `reflectance` | ρ, directional-hemispherical reflectance (any wi)   | [0, 1] |

Scene file: ``{ model = "lambertian", reflectance = 0.10 }`` (the seed paper's
diaphragm edge, case 1). Sampling is cosine-weighted, so every sample carries
weight ρ exactly.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from lensmount.physics.bsdf.base import BSDF, BSDFS, COS_EPS, BSDFParams, as_rows, dot, tangent_frame


class LambertianParams(BSDFParams):
    reflectance: float = Field(ge=0.0, le=1.0)


@BSDFS.register("lambertian", LambertianParams)
class Lambertian(BSDF):
    """f(wi, wo) = ρ/π for wi, wo above the surface; albedo = tis = ρ."""

    name = "lambertian"
    lobe_half_width_deg = math.inf

    def __init__(self, params: LambertianParams):
        self.reflectance = params.reflectance
        self.tis = self.weight_bound = self.reflectance  # cosine-weighted: every sample carries ρ

    @property
    def params(self):
        return {"reflectance": self.reflectance}

    def eval(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        above = (dot(wi, n) > COS_EPS) & (dot(wo, n) > COS_EPS)
        return np.where(above, self.reflectance / math.pi, 0.0)

    def sample(self, wi, n, u):
        """Cosine-weighted hemisphere (Malley): a uniform point on the unit disc lifted to the hemisphere."""
        wi, n, u = as_rows(wi, "wi"), as_rows(n, "n"), np.asarray(u, dtype=np.float64)
        u = np.clip(u, 0.0, np.nextafter(1.0, 0.0))
        r = np.sqrt(u[:, 0])
        phi = 2.0 * math.pi * u[:, 1]
        cos_o = np.sqrt(np.maximum(1.0 - u[:, 0], 0.0))  # > 0 since u0 < 1
        t1, t2 = tangent_frame(n)
        wo = (r * np.cos(phi))[:, None] * t1 + (r * np.sin(phi))[:, None] * t2 + cos_o[:, None] * n
        live = (dot(wi, n) > COS_EPS) & (cos_o > COS_EPS)
        pdf = np.where(live, cos_o / math.pi, 0.0)
        weight = np.where(live, self.reflectance, 0.0)
        return wo, weight, pdf

    def pdf(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        cos_o = dot(wo, n)
        live = (dot(wi, n) > COS_EPS) & (cos_o > COS_EPS)
        return np.where(live, cos_o / math.pi, 0.0)

    def albedo(self, wi, n):
        wi, n = as_rows(wi, "wi"), as_rows(n, "n")
        return np.where(dot(wi, n) > COS_EPS, self.reflectance, 0.0)
