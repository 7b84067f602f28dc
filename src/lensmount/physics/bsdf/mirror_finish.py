"""The scatter finish of a mirror's coated face, as the light that did scatter sees it.

A mirror with a finish (micro-roughness, dust; `[assign] "surface:N"`) reflects R (its coating)
of what it receives: R·(1 − a(wi)) specularly and R·f(wi, wo) scattered, where f is the finish's
BSDF and a(wi) its albedo at that incidence (= its TIS at normal incidence). The tracer picks the
branch: a ray scatters with probability p and then carries R·a/p, else it reflects specularly with
R(1 − a)/(1 − p) (`Tracer.next_event`, p = max(a, 0.1)). So the scattered light, R·a in all, leaves
with the lobe f / a(wi), whose albedo is 1 at every incidence: that is this BSDF, the one the walk
samples at the mirror's face.

Not a model a scene file names (scene files name the finish; `scene.build` wraps it). `finish`
is the wrapped BSDF; `tis`, `lobe_half_width_deg` and `is_black` are its.
"""

from __future__ import annotations

import numpy as np

from lensmount.physics.bsdf.base import BSDF, as_rows


class MirrorFinish(BSDF):
    """f(wi, wo) / a(wi) of the wrapped finish (0 where a(wi) = 0)."""

    name = "mirror-finish"

    def __init__(self, finish: BSDF):
        if finish.is_delta:
            raise ValueError("a mirror's finish is the scatter on top of its specular reflection, not a mirror")
        self.finish = finish
        self.tis = finish.tis
        self.is_black = finish.is_black
        self.lobe_half_width_deg = finish.lobe_half_width_deg

    @property
    def params(self):
        return self.finish.params

    def __repr__(self) -> str:
        return f"MirrorFinish({self.finish!r})"

    def _inverse_albedo(self, wi, n) -> np.ndarray:
        a = self.finish.albedo(wi, n)
        return np.where(a > 0.0, 1.0 / np.where(a > 0.0, a, 1.0), 0.0)

    def eval(self, wi, wo, n):
        return self.finish.eval(wi, wo, n) * self._inverse_albedo(as_rows(wi, "wi"), as_rows(n, "n"))

    def sample(self, wi, n, u):
        wo, weight, pdf = self.finish.sample(wi, n, u)
        return wo, weight * self._inverse_albedo(as_rows(wi, "wi"), as_rows(n, "n")), pdf

    def pdf(self, wi, wo, n):
        return self.finish.pdf(wi, wo, n)

    def albedo(self, wi, n):
        return np.where(self.finish.albedo(wi, n) > 0.0, 1.0, 0.0)
