"""BSDF models, one per file, all with the same calls (docs/architecture.md, docs/bsdf.md).

    bsdf = make_bsdf("gaussian", reflectance=0.05, half_width_deg=5.0)
    wo, weight, pdf = bsdf.sample(wi, n, u)      # (N,3), (N,), (N,)
    f = bsdf.eval(wi, wo, n)                     # (N,) 1/sr

| model        | parameters                         | file          |
|--------------|------------------------------------|---------------|
| `absorber`   | —                                  | absorber.py   |
| `lambertian` | reflectance                        | lambertian.py |
| `gaussian`   | reflectance, half_width_deg        | gaussian.py   |
| `abg`        | A, B, g                            | abg.py        |
| `harvey`     | b0, L, S                           | harvey.py     |
| `mirror`     | reflectance (default 1)            | mirror.py     |
| `tabulated`  | rho, brdf (a measured table)       | tabulated.py  |

`make_bsdf` raises `lensmount.errors.InputError` (field = the parameter) for an
unknown model, an unknown parameter or a value out of range, including an ABg or
Harvey set whose TIS exceeds 1. The scene loader adds the file with `.located()`.
`MirrorFinish` (mirror_finish.py) is no model: `scene.build` wraps the finish a mirror's coated
face is given in it (the lobe of the light that scattered there).
"""

from __future__ import annotations

from lensmount.errors import InputError
from lensmount.physics.bsdf.absorber import Absorber
from lensmount.physics.bsdf.abg import ABg
from lensmount.physics.bsdf.base import BSDF, reject_unknown
from lensmount.physics.bsdf.gaussian import Gaussian
from lensmount.physics.bsdf.harvey import Harvey
from lensmount.physics.bsdf.lambertian import Lambertian
from lensmount.physics.bsdf.mirror import Mirror
from lensmount.physics.bsdf.mirror_finish import MirrorFinish
from lensmount.physics.bsdf.tabulated import Tabulated

MODELS: dict[str, type[BSDF]] = {
    "absorber": Absorber,
    "lambertian": Lambertian,
    "gaussian": Gaussian,
    "abg": ABg,
    "harvey": Harvey,
    "mirror": Mirror,
    "tabulated": Tabulated,
}


def make_bsdf(model: str, **params) -> BSDF:
    """The BSDF named `model` (case-insensitive) made from `params`; InputError if either is wrong."""
    key = str(model).strip().lower()
    if key not in MODELS:
        raise InputError(f"unknown BSDF model '{model}'", field="model", valid=", ".join(MODELS))
    return MODELS[key](**params)


__all__ = ["BSDF", "MODELS", "make_bsdf", "reject_unknown",
           "Absorber", "Lambertian", "Gaussian", "ABg", "Harvey", "Mirror",
           "Tabulated", "MirrorFinish"]
