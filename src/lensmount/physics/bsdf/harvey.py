"""Harvey–Shack scatter model (the smooth-surface "Harvey" BSDF of stray-light analysis).

| parameter | meaning                                                          | valid     |
|-----------|------------------------------------------------------------------|-----------|
| `b0`      | f at the specular direction, 1/sr                                 | ≥ 0       |
| `L`       | shoulder: the lobe is flat for |β − β0| ≲ L (direction cosines)   | > 0       |
| `S`       | slope of the fall-off in log f vs log |β − β0| (≤ 0)             | [−10, 0]  |

    f(wi, wo) = b0 · (1 + (|β − β0| / L)²)^(S/2)

with β, β0 the projections of wo and of the mirror direction of wi on the
surface. Scene file: ``{ model = "harvey", b0 = 10.0, L = 0.01, S = -1.5 }``.
The set is rejected when TIS = ∫_{|β|<1} f d²β exceeds 1; `lobe_half_width_deg`
is arcsin(L·√(2^(−2/S) − 1)), where f falls to b0/2 at normal incidence (inf for
S = 0). Sampling, pdf and albedo: see `radial.py`.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from lensmount.physics.bsdf.base import BSDFS, BSDFParams
from lensmount.physics.bsdf.radial import DirectionCosineLobe


class HarveyParams(BSDFParams):
    b0: float = Field(ge=0.0)
    L: float = Field(gt=0.0)
    S: float = Field(ge=-10.0, le=0.0)


@BSDFS.register("harvey", HarveyParams)
class Harvey(DirectionCosineLobe):
    """f = b0 (1 + (|β − β0|/L)²)^(S/2); reciprocal; TIS ≤ 1 enforced."""

    name = "harvey"

    def __init__(self, params: HarveyParams):
        self.b0, self.L, self.S = params.b0, params.L, params.S
        exponent = -2.0 * math.log(2.0) / self.S if self.S < 0.0 else math.inf  # (1 + (ρ/L)²) = 2^(−2/S)
        half = self.L * math.sqrt(math.expm1(exponent)) if exponent < 700.0 else math.inf
        self.lobe_half_width_deg = math.degrees(math.asin(half)) if half < 1.0 else math.inf
        self._build(min(self.L, 1.0), field="b0",
                    valid="b0, L, S whose TIS ∫_{|β|<1} f d²β is at most 1 (lower b0)")

    @property
    def params(self):
        return {"b0": self.b0, "L": self.L, "S": self.S}

    def profile(self, rho):
        return self.b0 * np.power(1.0 + (np.maximum(rho, 0.0) / self.L) ** 2, 0.5 * self.S)
