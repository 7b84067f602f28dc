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

Each model is a file of this folder: its `BSDFParams` (the keys a finish gives, with their ranges) and its
class, registered by name in `BSDFS` (base.py); `make_bsdf` is `BSDFS.create`. It raises
`lensmount.errors.InputError` (field = the parameter) for an unknown model, an unknown parameter or a
value out of range, including an ABg or Harvey set whose TIS exceeds 1. The scene loader adds the file
with `.located()`.
`MirrorFinish` (mirror_finish.py) is no model: `scene.build` wraps the finish a mirror's coated
face is given in it (the lobe of the light that scattered there).
"""

from __future__ import annotations

from lensmount.physics.bsdf.absorber import Absorber
from lensmount.physics.bsdf.abg import ABg
from lensmount.physics.bsdf.base import BSDF, BSDFS, BSDFParams
from lensmount.physics.bsdf.gaussian import Gaussian
from lensmount.physics.bsdf.harvey import Harvey
from lensmount.physics.bsdf.lambertian import Lambertian
from lensmount.physics.bsdf.mirror import Mirror
from lensmount.physics.bsdf.mirror_finish import MirrorFinish
from lensmount.physics.bsdf.tabulated import Tabulated


def make_bsdf(model: str, **params) -> BSDF:
    """The BSDF named `model` (case-insensitive) made from `params`; InputError if either is wrong."""
    name = str(model).strip().lower()
    BSDFS.entry(name, field="model")  # an unknown model is the `model` key's error, not its parameters'
    return BSDFS.create(name, params)


__all__ = ["BSDF", "BSDFS", "BSDFParams", "make_bsdf",
           "Absorber", "Lambertian", "Gaussian", "ABg", "Harvey", "Mirror",
           "Tabulated", "MirrorFinish"]
