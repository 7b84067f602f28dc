"""ABg scatter model, the stray-light industry's standard (FRED, Zemax, ASAP).

| parameter | meaning                                                         | valid    |
|-----------|-----------------------------------------------------------------|----------|
| `A`       | scale, 1/sr (f at the specular direction is A/B)                 | ≥ 0      |
| `B`       | roll-off: the lobe is flat (A/B) for |β − β0| ≲ B^(1/g)          | > 0      |
| `g`       | slope of the fall-off, f ∝ |β − β0|^(−g) beyond the shoulder     | [0, 10]  |

    f(wi, wo) = A / (B + |β − β0|^g)

with β, β0 the projections of wo and of the mirror direction of wi on the
surface (direction cosines). Scene file: ``{ model = "abg", A = 1e-3, B = 1e-4, g = 2 }``.
The set is rejected when TIS = ∫_{|β|<1} A/(B + |β|^g) d²β exceeds 1 (computed at
load time by quadrature); `lobe_half_width_deg` is the angle arcsin(B^(1/g)) at which f
falls to half its peak at normal incidence (inf when g = 0 or B^(1/g) ≥ 1).
Sampling, pdf and albedo: see `radial.py`.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from lensmount.physics.bsdf.base import BSDFS, BSDFParams
from lensmount.physics.bsdf.radial import DirectionCosineLobe


class ABgParams(BSDFParams):
    A: float = Field(ge=0.0)
    B: float = Field(gt=0.0)
    g: float = Field(ge=0.0, le=10.0)


@BSDFS.register("abg", ABgParams)
class ABg(DirectionCosineLobe):
    """f = A / (B + |β − β0|^g); reciprocal; TIS ≤ 1 enforced."""

    name = "abg"

    def __init__(self, params: ABgParams):
        self.A, self.B, self.g = params.A, params.B, params.g
        shoulder = self.B ** (1.0 / self.g) if self.g > 0.0 else math.inf
        self.lobe_half_width_deg = math.degrees(math.asin(shoulder)) if shoulder < 1.0 else math.inf
        self._build(min(shoulder, 1.0), field="A",
                    valid="A, B, g whose TIS ∫_{|β|<1} A/(B + |β|^g) d²β is at most 1 (lower A or raise B)")

    @property
    def params(self):
        return {"A": self.A, "B": self.B, "g": self.g}

    def profile(self, rho):
        return self.A / (self.B + np.power(np.maximum(rho, 0.0), self.g))
