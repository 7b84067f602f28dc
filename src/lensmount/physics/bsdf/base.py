"""What every BSDF offers, and the small geometry every model shares.

Conventions (every model, every caller): `wi` (toward the light) and `wo`
(toward the viewer) are (N, 3) unit vectors pointing AWAY from the surface;
`n` (N, 3) is the unit normal on the side of `wi` (the caller flips it).
Reflection only: a `wo` or `wi` at or below the surface gives f = 0.

Dead lanes: `sample` may draw a direction that is not a reflection (below the
horizon, or outside the unit disc of direction cosines). Such a lane comes back
with weight 0 and pdf 0 and a finite unit `wo` that means nothing. `pdf`
returns 0 there too, so the live samples have exactly the density `pdf`, whose
integral over the hemisphere is the probability of a live sample (≤ 1).

Delta lobes (`is_delta`, the mirror): `eval` and `pdf` are 0 for every
direction pair (the lobe has no density); `sample` returns the mirror
direction with pdf = 1 (the discrete probability of the lobe, as pbrt does)
and weight = the reflectance.

Nothing here returns NaN or Inf: arccos/sqrt arguments are clamped and every
division is guarded.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict

from lensmount.registry import Registry

# Cosines at or below this count as "at the horizon": such directions carry no
# projected solid angle, and treating them as dead avoids 0/0 downstream.
COS_EPS = 1e-12
TINY = 1e-300


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (N, 3) arrays -> (N,)."""
    return np.einsum("ij,ij->i", a, b)


def mirror(w: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Specular direction of w about n: 2(n·w)n − w, (N, 3). A rotation by π about n, hence its own inverse."""
    return 2.0 * dot(n, w)[:, None] * n - w


def tangent_frame(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (N, 3) completing the unit vectors `v` (N, 3) to a right-handed frame.

    Duff et al. (2017) branchless basis: continuous except across v_z = 0's sign, no division by ~0.
    """
    sign = np.where(v[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + v[:, 2])
    b = v[:, 0] * v[:, 1] * a
    t1 = np.stack([1.0 + sign * v[:, 0] ** 2 * a, sign * b, -sign * v[:, 0]], axis=1)
    t2 = np.stack([b, sign + v[:, 1] ** 2 * a, -v[:, 1]], axis=1)
    return t1, t2


def normalize(v: np.ndarray) -> np.ndarray:
    """Unit rows of v (N, 3); a zero row becomes (0, 0, 1) rather than NaN."""
    length = np.linalg.norm(v, axis=1, keepdims=True)
    out = v / np.maximum(length, TINY)
    bad = length[:, 0] < TINY
    if bad.any():
        out[bad] = (0.0, 0.0, 1.0)
    return out


def as_rows(a, name: str = "vector") -> np.ndarray:
    """(N, 3) float64 view of `a` (a single (3,) vector becomes (1, 3))."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {arr.shape}")
    return arr


class BSDF:
    """Base of every model. Subclasses set the class attributes and implement the four calls.

    Attributes:
        name: the model's name in scene files ("lambertian", ...).
        tis: total integrated scatter at normal incidence = albedo(n, n) (the mirror's is its reflectance).
        is_delta: True for the mirror (no density; see module docstring).
        is_black: True for the absorber (ends paths).
        lobe_half_width_deg: half width at half maximum of the lobe around the specular direction,
            degrees; inf for a lobe as wide as the hemisphere (Lambertian), 0 for the mirror.
        weight_bound: the largest weight f·cosθo/pdf `sample` can return, for any wi (inf: the model
            states none). What bounds a forward photon's flux (`integrators.walk.gain_bound`).
    """

    name: str = "bsdf"
    tis: float = 0.0
    is_delta: bool = False
    is_black: bool = False
    lobe_half_width_deg: float = math.inf
    weight_bound: float = math.inf

    @property
    def params(self) -> dict:
        """The parameters the model was made with (for summaries)."""
        return {}

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        return f"{type(self).__name__}({inner})"

    # -- the four calls ------------------------------------------------------------------
    def eval(self, wi: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
        """BSDF value f (N,) in 1/sr; 0 where wi or wo is at or below the surface."""
        raise NotImplementedError

    def sample(self, wi: np.ndarray, n: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Draw wo for each lane from u (N, 2) in [0, 1).

        Returns wo (N, 3) unit, weight (N,) = f·cosθo/pdf (0 on dead lanes), pdf (N,) in 1/sr.
        """
        raise NotImplementedError

    def pdf(self, wi: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Solid-angle density (N,) of `sample`'s live output at wo; 0 below the horizon."""
        raise NotImplementedError

    def albedo(self, wi: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Directional-hemispherical reflectance (N,) = ∫ f(wi, wo) cosθo dωo over the hemisphere."""
        raise NotImplementedError


class BSDFParams(BaseModel):
    """Base of every model's parameters (a finish's table less its `model`): unknown keys are errors, numbers are
    finite numbers (a string or a boolean is not one), ranges are the fields' own."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


# Every model: a file of this folder with its `BSDFParams` that registers `@BSDFS.register(name, Params)`;
# `BSDFS.create(name, params)` checks the parameters and makes it (docs/architecture.md, "Where to add a BSDF").
BSDFS: Registry[BSDF] = Registry("BSDF model", where="a finish's model", implementations="lensmount.physics.bsdf")


class TabulatedAlbedo:
    """Mixin: `albedo` interpolated from `_albedo_exact` (slow quadrature) over the elevation of wi.

    albedo depends on wi only through cosθi for these isotropic models. The table is built
    on first use: a cubic spline in ln(elevation), 48 nodes per decade from 10⁻⁹ rad to
    0.25 rad (fine enough for a 0.01° lobe grazing the horizon) and every 0.6° above; its
    agreement with the quadrature is tested to 10⁻⁶. Normal incidence is a node, so albedo(n) = tis exactly.
    """

    _ELEVATION_MIN = 1e-9
    _table = None

    def _albedo_exact(self, ci: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def albedo(self, wi, n):
        wi, n = as_rows(wi, "wi"), as_rows(n, "n")
        ci = dot(wi, n)
        if self._table is None:
            from scipy.interpolate import CubicSpline  # lazy: keeps lensmount --help from loading scipy.interpolate
            log_e = np.linspace(math.log(self._ELEVATION_MIN), math.log(0.5 * math.pi), 48 * 10)
            log_e = np.union1d(log_e[log_e < math.log(0.25)], np.log(np.linspace(0.25, 0.5 * math.pi, 128)))
            values = self._albedo_exact(np.sin(np.exp(log_e)))
            values[-1] = self._albedo_exact(np.ones(1))[0]
            self._table = CubicSpline(log_e, values)
        elevation = np.arcsin(np.clip(ci, self._ELEVATION_MIN, 1.0))
        out = self._table(np.log(np.clip(elevation, self._ELEVATION_MIN, 0.5 * math.pi)))
        return np.where(ci > COS_EPS, np.maximum(out, 0.0), 0.0)
