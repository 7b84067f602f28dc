"""Surface scatter models (BSDFs) for stray-light scenes — the public names.

Every model has the same four calls on (N, 3) float64 unit vectors, both
pointing away from the surface, with `n` on the side of `wi`:

    f = bsdf.eval(wi, wo, n)                 # (N,) BSDF in 1/sr, 0 below the horizon
    wo, weight, pdf = bsdf.sample(wi, n, u)  # u (N, 2) uniforms; weight = f·cosθo/pdf
    p = bsdf.pdf(wi, wo, n)                  # (N,) solid-angle density of `sample`
    a = bsdf.albedo(wi, n)                   # (N,) ∫ f cosθo dωo
    bsdf.tis, bsdf.is_delta, bsdf.is_black, bsdf.lobe_half_width_deg

Make one by name, as scene files do (unknown names, unknown parameters and
out-of-range values raise `lensmount.errors.InputError`):

    >>> from lensmount.bsdf import make_bsdf
    >>> make_bsdf("gaussian", reflectance=0.05, half_width_deg=5.0).tis
    0.05

Models: `absorber`, `lambertian{reflectance}`, `gaussian{reflectance, half_width_deg}`,
`abg{A, B, g}`, `harvey{b0, L, S}`, `mirror{reflectance}`, `tabulated{rho, brdf}` (a measured
lobe; scene files name the measurement file instead). Definitions, parameter
ranges and how each is sampled: docs/bsdf.md and each class's module.
"""

from __future__ import annotations

from lensmount.trace.bsdf import (BSDF, MODELS, ABg, Absorber, Gaussian, Harvey, Lambertian, Mirror, Tabulated,
                                  make_bsdf)

__all__ = ["BSDF", "MODELS", "make_bsdf", "Absorber", "Lambertian", "Gaussian", "ABg", "Harvey", "Mirror",
           "Tabulated"]
