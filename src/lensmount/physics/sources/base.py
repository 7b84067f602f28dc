"""What every light source offers, where a scene places it, and the registry of kinds (`SOURCES`).

Direction convention: `off_axis_deg` θ from the +z axis, `azimuth_deg` φ the direction of the
tilt in the object space: φ = 90° puts the source toward +y, so its light travels toward −y:

    d = (−sin θ cos φ, −sin θ sin φ, cos θ).

θ > 90° puts the source behind the lens (d_z < 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, ClassVar, Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict

from lensmount.errors import InputError
from lensmount.physics.rays import RayBatch
from lensmount.registry import Registry
from lensmount.validation import did_you_mean

LIMB_DARKENING_U = 0.6
SUN_ANGULAR_DIAMETER_DEG = 0.53


class Source(Protocol):
    """What every light source offers the scene, the integrators and the run summary.

    at_infinity : a parallel beam from a direction (sun, collimated: images in E/E_sun; photon
        aiming at an edge and the deterministic ghost routes apply), or an object at a finite
        distance (images in E/E_ref, its own irradiance over the entrance pupil).
    emit(n, rng) -> (RayBatch whose weights are flux per photon, mean flux per photon).
    """

    at_infinity: ClassVar[bool]
    wavelength_weights: tuple[float, ...]

    @property
    def off_axis_deg(self) -> float: ...

    @property
    def half_angle_rad(self) -> float: ...

    @property
    def entering_fraction(self) -> float: ...

    @property
    def no_light_enters(self) -> str | None: ...

    def emit(self, n: int, rng: np.random.Generator) -> tuple[RayBatch, float]: ...


def _cos_deg(x: float) -> float:
    """cos of an angle in degrees, exact at multiples of 90° (cos 90° is 0, not 6e-17)."""
    x = math.fmod(float(x), 360.0)
    quarter = x / 90.0
    if quarter == round(quarter):
        return (1.0, 0.0, -1.0, 0.0)[int(round(quarter)) % 4]
    return math.cos(math.radians(x))


def _sin_deg(x: float) -> float:
    return _cos_deg(90.0 - float(x))


def source_direction(off_axis_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit propagation direction (3,) of light from a source at (θ, φ); exact at multiples of 90°."""
    st, ct = _sin_deg(off_axis_deg), _cos_deg(off_axis_deg)
    return np.array([-st * _cos_deg(azimuth_deg), -st * _sin_deg(azimuth_deg), ct])


def entering_fraction(off_axis_deg: float, half_angle_rad: float = 0.0, limb_darkening: bool = False) -> float:
    """Irradiance crossing the entrance plane (z = const, into +z) per unit source irradiance.

    The mean over the source's disc of max(d_z, 0): cos θ for a collimated source (exactly 0 at
    90° and beyond); for the sun, a grazing share remains until the whole disc is behind the
    plane (θ ≥ 90° + α): at θ = 90°, the upper half of a 0.53° sun still sends 9.8e-4 E_sun (2α/3π)
    across it. Quadrature over the disc (the same brightness law as `emit`)."""
    ct = _cos_deg(off_axis_deg)
    if half_angle_rad <= 0.0:
        return max(ct, 0.0)
    if off_axis_deg - math.degrees(half_angle_rad) >= 90.0:
        return 0.0
    st = _sin_deg(off_axis_deg)
    # Midpoint rule over equal-brightness annuli (inverse CDF of the radius) and azimuth.
    s = disc_radius_fraction((np.arange(256) + 0.5) / 256, limb_darkening)[:, None]
    psi = 2.0 * np.pi * (np.arange(512) + 0.5) / 512
    rho = s * half_angle_rad
    dz = np.cos(rho) * ct + np.sin(rho) * np.cos(psi)[None, :] * st  # ψ from the tilt toward +z
    return float(np.maximum(dz, 0.0).mean())


def no_light_enters_reason(off_axis_deg: float, half_angle_rad: float = 0.0) -> str | None:
    """Why no light crosses the entrance plane, or None when some does (see `entering_fraction`)."""
    if entering_fraction(off_axis_deg, half_angle_rad) > 0.0:
        return None
    what = (f"the sun (disc radius {math.degrees(half_angle_rad):.3f}°) lies entirely" if half_angle_rad > 0
            else "the source lies")
    return (f"{what} behind the entrance plane ({off_axis_deg:g}° off axis): no light enters the front "
            "opening, so the flux entering the aperture is zero; light could only reach the detector "
            "through another opening in the side or back of the assembly (traced all the same)")


def orthonormal_basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (3,) spanning the plane normal to unit d (3,)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


@dataclass(frozen=True)
class EmissionDisc:
    """Where photons start: centre (3,) mm, radius mm, normal = the source's central direction."""

    centre: tuple[float, float, float]
    radius: float

    @property
    def area(self) -> float:
        return math.pi * self.radius**2


def emission_disc(direction: np.ndarray, opening_z: float, opening_radius: float, clear_distance: float,
                  half_angle_rad: float = 0.0, margin: float = 0.02) -> EmissionDisc:
    """A disc normal to `direction` that covers the circular front opening (radius at z on the axis).

    It is set back by `clear_distance` (beyond the assembly's bounding sphere) against the light,
    and widened for the source's angular radius and a small margin, so every ray that can reach
    the opening from the source starts on it.
    """
    centre = np.array([0.0, 0.0, opening_z]) - clear_distance * np.asarray(direction)
    radius = opening_radius * (1.0 + margin) + clear_distance * math.tan(half_angle_rad) + 1e-3
    if float(np.asarray(direction)[2]) <= math.sin(half_angle_rad) + margin:
        # Grazing or from behind: the front opening is seen edge-on or not at all, and light can
        # reach the assembly anywhere (an open side or back); cover all of it, never drop it.
        radius = max(radius, clear_distance * (1.0 + margin))
    return EmissionDisc(tuple(float(x) for x in centre), float(radius))


_GRID = np.linspace(0.0, 1.0, 2049)


def disc_radius_fraction(u: np.ndarray, limb: bool) -> np.ndarray:
    """Radius on the unit solar disc for uniforms u: uniform area, or limb-darkened brightness."""
    if not limb:
        return np.sqrt(u)
    # pdf(s) ∝ s (1 − U (1 − sqrt(1 − s²))) on s in [0, 1]; inverse CDF by table (vectorised).
    s = _GRID
    dens = s * (1.0 - LIMB_DARKENING_U * (1.0 - np.sqrt(np.maximum(0.0, 1.0 - s * s))))
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(s))])
    return np.interp(u, cdf / cdf[-1], s)


# ---- Source kinds: what a scene file's [source] table may say, and how each kind is placed ----

@dataclass(frozen=True)
class Placement:
    """What the scene knows when it places a source (mm, assembly frame).

    opening_z, opening_radius : the front opening light enters by; clear_distance : from the
    opening's centre, beyond which nothing of the assembly lies; object_z : the lens's object
    plane (None: the object is at infinity); pupil() -> (z, radius) of the paraxial entrance pupil
    (asked for only by sources that need it: a lens without a stop has none and says so).
    """

    opening_z: float
    opening_radius: float
    clear_distance: float
    object_z: float | None
    pupil: Callable[[], tuple[float, float]]
    wavelength_weights: tuple[float, ...] = (1.0,)


class SourceParams(BaseModel):
    """The [source] table of a scene file: `type` names the kind, the other keys are the kind's own
    (unknown keys are errors). Each kind subclasses this with `type: Literal[name]`."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)  # no key takes NaN or inf
    at_infinity: ClassVar[bool]
    type: str


# Every kind: its `SourceParams` and a factory `(params, at: Placement) -> Source`, registered
# `@SOURCES.register(name, Params)` (docs/architecture.md, "Where to add a source").
SOURCES: Registry[Source] = Registry("source type", where="the scene's [source] table",
                                     implementations="lensmount.physics.sources")


def source_params(table: dict) -> SourceParams:
    """The validated [source] table; an InputError (field `source.KEY`) names what is wrong."""
    name = table.get("type", "sun")
    model = SOURCES.entry(name, field="source.type").params
    for key in table:  # a key of another kind would otherwise read as a plain typo
        if key not in model.model_fields:
            others = [f"'{n}'" for n in SOURCES.names() if key in SOURCES.entry(n).params.model_fields]
            guess = did_you_mean(key, model.model_fields)
            said = (f"{key} applies to type = {' or '.join(others)} only" if others else
                    f"unknown key '{key}'" + (f" (did you mean '{guess}'?)" if guess else ""))
            raise InputError(f"{said}, not to a {name} source", field=f"source.{key}",
                             valid=f"the keys of a {name} source: " + ", ".join(model.model_fields))
    return SOURCES.parse(name, table, field="source")


__all__ = ["Source", "Placement", "SourceParams", "SOURCES", "source_params", "EmissionDisc", "emission_disc",
           "source_direction", "orthonormal_basis", "entering_fraction", "no_light_enters_reason",
           "disc_radius_fraction", "LIMB_DARKENING_U", "SUN_ANGULAR_DIAMETER_DEG"]
