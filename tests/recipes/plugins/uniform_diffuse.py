"""A BSDF model added the way docs/architecture.md says ("Where to add a BSDF"): this file, which registers
itself in `BSDFS`, and its line in the plug-in package's entry points; nothing of lensmount touched.

A Lambertian reflector sampled uniformly over the hemisphere instead of by cosine:

| parameter     | meaning                                           | valid  |
|---------------|---------------------------------------------------|--------|
| `reflectance` | ρ, directional-hemispherical reflectance (any wi) | [0, 1] |

    f = ρ/π,  pdf = 1/(2π),  weight = f cosθo / pdf = 2ρ cosθo

Scene file: ``{ model = "uniform-diffuse", reflectance = 0.1 }``. The same BSDF as `lambertian`, so a
scene gives the same expected image with either; only the spread of the estimate differs.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from lensmount.physics.bsdf.base import BSDF, BSDFS, COS_EPS, BSDFParams, as_rows, dot, tangent_frame


class UniformDiffuseParams(BSDFParams):
    reflectance: float = Field(ge=0.0, le=1.0)


@BSDFS.register("uniform-diffuse", UniformDiffuseParams)
class UniformDiffuse(BSDF):
    """f = ρ/π, sampled uniformly over the hemisphere."""

    name = "uniform-diffuse"

    def __init__(self, params: UniformDiffuseParams):
        self.reflectance = self.tis = params.reflectance

    @property
    def params(self):
        return {"reflectance": self.reflectance}

    def eval(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        return np.where((dot(wi, n) > COS_EPS) & (dot(wo, n) > COS_EPS), self.reflectance / math.pi, 0.0)

    def sample(self, wi, n, u):
        wi, n, u = as_rows(wi, "wi"), as_rows(n, "n"), np.asarray(u, dtype=np.float64)
        cos_o = 1.0 - np.clip(u[:, 0], 0.0, np.nextafter(1.0, 0.0))  # uniform in (0, 1]: uniform on the hemisphere
        sin_o = np.sqrt(np.maximum(1.0 - cos_o * cos_o, 0.0))
        phi = 2.0 * math.pi * u[:, 1]
        t1, t2 = tangent_frame(n)
        wo = (sin_o * np.cos(phi))[:, None] * t1 + (sin_o * np.sin(phi))[:, None] * t2 + cos_o[:, None] * n
        live = (dot(wi, n) > COS_EPS) & (cos_o > COS_EPS)
        return wo, np.where(live, 2.0 * self.reflectance * cos_o, 0.0), np.where(live, 0.5 / math.pi, 0.0)

    def pdf(self, wi, wo, n):
        wi, wo, n = as_rows(wi, "wi"), as_rows(wo, "wo"), as_rows(n, "n")
        return np.where((dot(wi, n) > COS_EPS) & (dot(wo, n) > COS_EPS), 0.5 / math.pi, 0.0)

    def albedo(self, wi, n):
        wi, n = as_rows(wi, "wi"), as_rows(n, "n")
        return np.where(dot(wi, n) > COS_EPS, self.reflectance, 0.0)
