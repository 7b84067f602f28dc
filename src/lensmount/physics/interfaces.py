"""What light does at a glass surface: Fresnel, coatings (Snell refraction and TIR: optics.snell).

All functions are vectorised over N rays and NaN-free by construction.

Reflectance and transmittance come from the thin-film characteristic matrix with tilted
admittances (Macleod, *Thin-film optical filters*, ch. 2): for polarisation s the admittance
of a medium is eta = n cos(theta), for p it is eta = n / cos(theta). A bare interface is the
identity matrix, so `uncoated` and `mgf2-quarter-wave` share one formula:

    [B, C] = M_film · [1, eta_2],   r = (eta_0 B − C) / (eta_0 B + C),
    R = |r|²,                        T = 4 eta_0 Re(eta_2) / |eta_0 B + C|².

R and T are computed independently (T is *not* 1 − R), so R + T = 1 is a real check
of the algebra. Beyond the critical angle cos(theta_2) is imaginary, Re(eta_2) = 0 and
T = 0 on its own (total internal reflection).

Coatings (the names used in lens and scene files):
    perfect-ar         R = 0 (T = 1) except under total internal reflection
    uncoated           Fresnel, average of s and p (unpolarised light)
    mgf2-quarter-wave  one MgF2 layer (n = 1.38), a quarter wave thick at 0.55 µm at normal incidence
    R=0.01             constant reflectance at every angle and wavelength (T = 1 − R; TIR still 1)
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from lensmount.errors import InputError

MGF2_INDEX = 1.38
MGF2_DESIGN_WAVELENGTH_UM = 0.55
_COS_FLOOR = 1e-12  # keeps n / cos(theta) finite at exactly grazing or critical incidence
_CONSTANT = re.compile(r"^\s*R\s*=\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*$")
COATING_NAMES = "perfect-ar, uncoated, mgf2-quarter-wave, or a constant reflectance such as R=0.01 (0 <= R <= 1)"


@dataclass(frozen=True)
class Coating:
    """A surface treatment. kind: 'perfect-ar' | 'uncoated' | 'mgf2-quarter-wave' | 'constant'."""

    kind: str
    reflectance: float = 0.0  # only for kind == 'constant'

    @property
    def name(self) -> str:
        return f"R={self.reflectance:g}" if self.kind == "constant" else self.kind


def parse_coating(text: str | None, *, file: str | None = None, field: str | None = None) -> Coating:
    """A coating from its name; None means perfect-ar (the seed paper's assumption)."""
    if text is None:
        return Coating("perfect-ar")
    name = str(text).strip().lower()
    if name in ("perfect-ar", "uncoated", "mgf2-quarter-wave"):
        return Coating(name)
    m = _CONSTANT.match(str(text))
    if m:
        r = float(m.group(1))
        if 0.0 <= r <= 1.0:
            return Coating("constant", r)
    raise InputError(f"unknown coating '{text}'", file=file, field=field, valid=COATING_NAMES)


PROTECTED_ALUMINIUM_R = 0.90  # a mirror's reflectance unless a constant coating (R=0.95) says otherwise


def mirror_reflectance(coating: Coating) -> float:
    """Reflectance of a mirror surface: a constant coating's R, else protected aluminium's
    (about 0.90 over the visible; Fresnel names such as perfect-ar describe glass, not a mirror)."""
    return coating.reflectance if coating.kind == "constant" else PROTECTED_ALUMINIUM_R


def facing(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Normals n (N, 3) turned to the side rays travelling along d (N, 3) arrive from (n · d ≤ 0)."""
    return n * np.where(np.einsum("ij,ij->i", n, d) > 0.0, -1.0, 1.0)[:, None]


def _admittances(n: np.ndarray, cos: np.ndarray):
    """(eta_s, eta_p) complex admittances of a medium for a (possibly complex) cos(theta)."""
    cos = np.where(np.abs(cos) < _COS_FLOOR, _COS_FLOOR, cos)
    return n * cos, n / cos


def _complex_cos(n0: np.ndarray, sin0: np.ndarray, n: np.ndarray | float) -> np.ndarray:
    """cos(theta) in medium n from the invariant n0 sin(theta_0); imaginary when evanescent.

    The sign is the one that makes the field decay (Im >= 0 with exp(+i k z cos) convention),
    which keeps Re(eta) >= 0 and so T >= 0.
    """
    s = (n0 * sin0) / n
    c = np.sqrt((1.0 - s * s).astype(np.complex128))
    return np.where(c.imag < 0, -c, c)


def fresnel_rt(n1: np.ndarray, n2: np.ndarray, cos_i: np.ndarray, coating: Coating,
               wavelength_um: np.ndarray):
    """Reflectance and transmittance for s and p light going from medium n1 into n2.

    n1, n2, cos_i, wavelength_um : (N,) (cos_i in [0, 1]). Returns (R_s, R_p, T_s, T_p), each (N,),
    in [0, 1]. For 'perfect-ar' and 'constant' coatings R and T are the coating's values
    (except total internal reflection, which always reflects everything).
    """
    n1 = np.asarray(n1, np.float64)
    n2 = np.asarray(n2, np.float64)
    cos_i = np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0)
    sin_i = np.sqrt(np.maximum(0.0, 1.0 - cos_i * cos_i))
    tir = n1 * sin_i > n2
    if coating.kind in ("perfect-ar", "constant"):
        r = np.where(tir, 1.0, coating.reflectance if coating.kind == "constant" else 0.0)
        return r, r, 1.0 - r, 1.0 - r
    cos0 = cos_i.astype(np.complex128)
    cos2 = _complex_cos(n1, sin_i, n2)
    e0s, e0p = _admittances(n1, cos0)
    e2s, e2p = _admittances(n2, cos2)
    out = []
    if coating.kind == "uncoated":
        # a bare interface: the identity matrix, for s and for p
        mats = [(np.ones_like(cos0), np.zeros_like(cos0), np.zeros_like(cos0), np.ones_like(cos0))] * 2
    elif coating.kind == "mgf2-quarter-wave":
        wl = np.asarray(wavelength_um, np.float64)
        thickness = MGF2_DESIGN_WAVELENGTH_UM / (4.0 * MGF2_INDEX)
        cosf = _complex_cos(n1, sin_i, MGF2_INDEX)
        delta = 2.0 * np.pi * MGF2_INDEX * thickness * cosf / wl
        efs, efp = _admittances(MGF2_INDEX, cosf)
        cd, sd = np.cos(delta), np.sin(delta)
        mats = [(cd, 1j * sd / ef, 1j * ef * sd, cd) for ef in (efs, efp)]
    else:  # pragma: no cover - parse_coating admits nothing else
        raise ValueError(coating.kind)
    for (m11, m12, m21, m22), e0, e2 in zip(mats, (e0s, e0p), (e2s, e2p)):
        b = m11 + m12 * e2
        c = m21 + m22 * e2
        den = e0 * b + c
        den = np.where(np.abs(den) < 1e-300, 1e-300, den)
        r = np.abs((e0 * b - c) / den) ** 2
        t = 4.0 * e0.real * e2.real / np.abs(den) ** 2
        out.append((np.clip(r, 0.0, 1.0), np.clip(t, 0.0, 1.0)))
    (rs, ts), (rp, tp) = out
    rs, rp = np.where(tir, 1.0, rs), np.where(tir, 1.0, rp)
    ts, tp = np.where(tir, 0.0, ts), np.where(tir, 0.0, tp)
    return rs, rp, ts, tp


def reflectance(n1, n2, cos_i, coating: Coating, wavelength_um) -> np.ndarray:
    """Unpolarised reflectance (R_s + R_p) / 2, (N,)."""
    rs, rp, _, _ = fresnel_rt(n1, n2, cos_i, coating, wavelength_um)
    return 0.5 * (rs + rp)


__all__ = ["Coating", "parse_coating", "mirror_reflectance", "PROTECTED_ALUMINIUM_R", "facing",
           "fresnel_rt", "reflectance", "COATING_NAMES"]
