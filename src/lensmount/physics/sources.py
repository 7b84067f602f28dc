"""Light sources: the sun (a 0.53° disc) and a collimated point source, both at infinity, and an
object at a finite distance (`ObjectSource`: a point or a Lambertian disc, see its docstring).

Direction convention: `off_axis_deg` θ from the +z axis, `azimuth_deg` φ the direction of the
tilt in the object space: φ = 90° puts the source toward +y, so its light travels toward −y:

    d = (−sin θ cos φ, −sin θ sin φ, cos θ).

θ > 90° puts the source behind the lens (d_z < 0).

Flux bookkeeping (what makes results independent of the emission disc): photons start
uniformly on a disc of area A_S normal to the central direction, placed outside the
assembly and covering its front opening; a source of irradiance E_sun sends E_sun · A_S
through that disc, so each of N photons carries Φ = A_S / N in units of E_sun · mm². Any
larger disc gives the same detector irradiance (more photons simply miss).

Sun directions: uniform over the solar disc of angular radius α (cos-weighting across
0.27° is 1 − 1e-5, ignored) or, with `limb_darkening`, weighted by the standard linear law
I(μ)/I(1) = 1 − u (1 − μ), u = 0.6, μ = cos of the angle from the disc centre seen on the sun.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable, ClassVar, Literal, Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from lensmount.errors import InputError
from lensmount.physics.rays import RayBatch
from lensmount.validation import did_you_mean, input_error

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


class _ParallelBeam:
    """What the sun and a collimated source share: a beam from (off_axis_deg, azimuth_deg) whose
    photons start on `disc`, inside a cone of half-angle `half_angle_rad`."""

    at_infinity: ClassVar[bool] = True

    @property
    def direction(self) -> np.ndarray:
        return source_direction(self.off_axis_deg, self.azimuth_deg)

    @property
    def entering_fraction(self) -> float:
        """Irradiance through the entrance plane / E_sun (see `entering_fraction`)."""
        return entering_fraction(self.off_axis_deg, self.half_angle_rad, self.limb_darkening)

    @property
    def no_light_enters(self) -> str | None:
        """The reason no light enters the front opening, for the run summary; None when some does."""
        return no_light_enters_reason(self.off_axis_deg, self.half_angle_rad)

    def emit(self, n: int, rng: np.random.Generator) -> tuple[RayBatch, float]:
        """n photons: (RayBatch with weight = flux per photon, flux per photon [E_sun·mm²])."""
        return _emit(self, n, rng, self.half_angle_rad, self.limb_darkening)


@dataclass(frozen=True)
class SunSource(_ParallelBeam):
    """The sun: angular disc of `angular_diameter_deg`, at (off_axis_deg, azimuth_deg).

    wavelength_weights (W,) are the source's relative spectral weights over the scene's
    wavelengths (photon wavelengths are drawn in proportion).
    """

    off_axis_deg: float
    azimuth_deg: float
    disc: EmissionDisc
    angular_diameter_deg: float = SUN_ANGULAR_DIAMETER_DEG
    limb_darkening: bool = False
    wavelength_weights: tuple[float, ...] = (1.0,)

    @property
    def half_angle_rad(self) -> float:
        return 0.5 * math.radians(self.angular_diameter_deg)


@dataclass(frozen=True)
class CollimatedSource(_ParallelBeam):
    """A point source at infinity (a perfectly collimated beam), for PST sweeps."""

    limb_darkening: ClassVar[bool] = False  # a point has no disc
    half_angle_rad: ClassVar[float] = 0.0
    off_axis_deg: float
    azimuth_deg: float
    disc: EmissionDisc
    wavelength_weights: tuple[float, ...] = (1.0,)


# Midpoint quadrature of the entrance pupil (rings × azimuths) and of a disc source, for the
# flux an object source sends into the pupil: smooth integrands, ~1e-5 relative.
_PUPIL_RINGS, _PUPIL_AZIMUTHS = 48, 96
_DISC_RINGS, _DISC_AZIMUTHS = 12, 24


def _disc_points(centre, radius: float, rings: int, azimuths: int, normal_z: bool = True):
    """Midpoint-rule nodes (M, 3) and areas (M,) of a disc normal to z (one node for radius 0)."""
    c = np.asarray(centre, np.float64)
    if radius <= 0.0:
        return c[None, :], np.ones(1)
    edges = radius * np.sqrt(np.arange(rings + 1) / rings)  # equal-area rings
    r = np.sqrt(0.5 * (edges[1:] ** 2 + edges[:-1] ** 2))
    phi = 2.0 * np.pi * (np.arange(azimuths) + 0.5) / azimuths
    rr, pp = np.meshgrid(r, phi, indexing="ij")
    pts = np.column_stack([c[0] + (rr * np.cos(pp)).ravel(), c[1] + (rr * np.sin(pp)).ravel(),
                           np.full(rr.size, c[2])])
    return pts, np.full(rr.size, math.pi * radius**2 / rr.size)


@dataclass(frozen=True)
class ObjectSource:
    """An object at a finite distance: an isotropic point (radius 0) or a Lambertian disc facing
    +z (radius > 0), centred at `centre` (mm, assembly frame; usually on the lens's object plane).

    Units (what makes the stray fraction "of the light the lens accepts"): photons carry flux in
    units of E_ref·mm², where E_ref is the mean irradiance the source makes over the paraxial
    entrance pupil (disc of radius `pupil_radius` at z = `pupil_z`): E_ref · A_EP is the flux it
    sends into the pupil, Φ_EP = I · Ω_EP (point of intensity I; Ω_EP the solid angle of the cone of
    lines from the point through the pupil, real or virtual) or L · G_EP (disc of radiance L; G_EP
    its étendue into the pupil). So `entering_fraction` is 1 and the loop's aperture flux A_EP ·
    1 is Φ_EP: stray fraction = detector flux / flux into the entrance pupil, and images read
    E / E_ref, as E / E_sun for the sun.

    Photons start on the source (uniform over the disc) and leave uniformly inside the cone from
    their start that just holds the sphere around the front opening (`aim_z`, `aim_radius`); a
    point inside that sphere emits over the +z hemisphere. Light the cone leaves out cannot enter
    the front opening.
    """

    at_infinity: ClassVar[bool] = False
    centre: tuple[float, float, float]
    radius: float
    aim_z: float
    aim_radius: float
    pupil_z: float
    pupil_radius: float
    wavelength_weights: tuple[float, ...] = (1.0,)

    @property
    def entering_fraction(self) -> float:
        return 1.0

    @property
    def off_axis_deg(self) -> float:
        """Angle of the source's centre off the axis seen from the entrance pupil's centre (the
        object-space field angle of its chief ray), degrees."""
        x, y, z = self.centre
        return math.degrees(math.atan2(math.hypot(x, y), max(self.pupil_z - z, 0.0)))

    @property
    def half_angle_rad(self) -> float:
        """Angular radius of the disc seen from the entrance pupil's centre (0 for a point)."""
        return math.atan2(self.radius, max(self.pupil_z - self.centre[2], 0.0))

    @property
    def no_light_enters(self) -> str | None:
        return None

    @functools.cached_property
    def pupil_etendue(self) -> float:
        """Ω_EP (point, sr) or G_EP / A_source (disc, sr): what the source sends into the entrance
        pupil per unit intensity, resp. per unit radiance and source area."""
        pupil, dA = _disc_points((0.0, 0.0, self.pupil_z), self.pupil_radius, _PUPIL_RINGS, _PUPIL_AZIMUTHS)
        src, dS = _disc_points(self.centre, self.radius, _DISC_RINGS, _DISC_AZIMUTHS)
        v = pupil[None, :, :] - src[:, None, :]
        r2 = np.maximum(np.einsum("ijk,ijk->ij", v, v), 1e-300)
        cos_p = np.abs(v[..., 2]) / np.sqrt(r2)  # lines through a virtual pupil count as well
        lambert = cos_p if self.radius > 0.0 else 1.0  # a disc facing the pupil plane: the same cosine
        g = (lambert * cos_p / r2 * dA[None, :]).sum(axis=1)
        return float((g * dS).sum() / dS.sum())

    def emit(self, n: int, rng) -> tuple[RayBatch, float]:
        """n photons: (RayBatch with weight = flux per photon in E_ref·mm², mean flux per photon)."""
        u = rng.random((n, 5))
        origin = np.tile(np.asarray(self.centre, np.float64), (n, 1))
        if self.radius > 0.0:
            r = self.radius * np.sqrt(u[:, 0])
            origin[:, 0] += r * np.cos(2.0 * np.pi * u[:, 1])
            origin[:, 1] += r * np.sin(2.0 * np.pi * u[:, 1])
        to_aim = np.array([0.0, 0.0, self.aim_z]) - origin
        dist = np.linalg.norm(to_aim, axis=1)
        outside = dist > self.aim_radius
        axis = np.where(outside[:, None], to_aim / np.where(outside, dist, 1.0)[:, None], [0.0, 0.0, 1.0])
        cos_beta = np.where(outside, np.sqrt(np.maximum(0.0, 1.0 - (self.aim_radius / np.maximum(dist, 1e-300)) ** 2)),
                            0.0)
        cos_t = 1.0 - u[:, 2] * (1.0 - cos_beta)
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        psi = 2.0 * np.pi * u[:, 3]
        helper = np.where((np.abs(axis[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        e1 = np.cross(axis, helper)
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 = np.cross(axis, e1)
        direction = (cos_t[:, None] * axis + (sin_t * np.cos(psi))[:, None] * e1
                     + (sin_t * np.sin(psi))[:, None] * e2)
        solid_angle = 2.0 * np.pi * (1.0 - cos_beta)  # of each photon's cone (pdf 1 / solid_angle)
        lambert = np.maximum(direction[:, 2], 0.0) if self.radius > 0.0 else 1.0
        area = math.pi * self.pupil_radius**2
        weight = area * lambert * solid_angle / (max(n, 1) * self.pupil_etendue)
        w = np.asarray(self.wavelength_weights, np.float64)
        wavelength = rng.choice(len(w), size=n, p=w / w.sum()) if len(w) > 1 else np.zeros(n, np.int32)
        return RayBatch.make(origin, direction, weight=weight, wavelength=wavelength), float(weight.mean()) if n else 0.0


def _emit(source, n: int, rng: np.random.Generator, alpha: float, limb: bool) -> tuple[RayBatch, float]:
    d0 = source.direction
    e1, e2 = orthonormal_basis(d0)
    u = rng.random((n, 4))
    # Position: uniform on the disc.
    r = source.disc.radius * np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    origin = (np.asarray(source.disc.centre)[None, :] + (r * np.cos(phi))[:, None] * e1
              + (r * np.sin(phi))[:, None] * e2)
    # Direction: inside the source's cone of half-angle alpha.
    if alpha > 0.0:
        rho = disc_radius_fraction(u[:, 2], limb) * alpha  # small angle: uniform disc in angle space
        psi = 2.0 * np.pi * u[:, 3]
        direction = (np.cos(rho)[:, None] * d0 + (np.sin(rho) * np.cos(psi))[:, None] * e1
                     + (np.sin(rho) * np.sin(psi))[:, None] * e2)
    else:
        direction = np.broadcast_to(d0, (n, 3)).copy()
    w = np.asarray(source.wavelength_weights, np.float64)
    wavelength = rng.choice(len(w), size=n, p=w / w.sum()) if len(w) > 1 else np.zeros(n, np.int32)
    flux = source.disc.area / max(n, 1)
    return RayBatch.make(origin, direction, weight=np.full(n, flux), wavelength=wavelength), flux


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


class _AtInfinity(SourceParams):
    at_infinity: ClassVar[bool] = True
    off_axis_deg: float = Field(ge=0.0, le=180.0)
    azimuth_deg: float = 90.0


class SunParams(_AtInfinity):
    type: Literal["sun"] = "sun"
    angular_diameter_deg: float = Field(default=SUN_ANGULAR_DIAMETER_DEG, ge=0.0, le=10.0)
    limb_darkening: bool = False


class CollimatedParams(_AtInfinity):
    type: Literal["collimated"]


class PointParams(SourceParams):
    at_infinity: ClassVar[bool] = False
    type: Literal["point"]
    height_mm: float = Field(default=0.0, ge=0.0)
    azimuth_deg: float = 90.0
    z_mm: float | None = None


class DiscParams(PointParams):
    type: Literal["disc"]  # type: ignore[assignment]
    radius_mm: float = Field(gt=0.0)


@dataclass(frozen=True)
class SourceKind:
    """A kind of source: its scene-file keys and how it is built at a placement."""

    params: type[SourceParams]
    build: Callable[[SourceParams, Placement], Source]


SOURCE_KINDS: dict[str, SourceKind] = {}


def register_source(name: str, params: type[SourceParams], build: Callable[[SourceParams, Placement], Source]) -> None:
    """Make `type = name` a source kind of scene files (docs/architecture.md, "Where to add a source")."""
    SOURCE_KINDS[name] = SourceKind(params, build)


def source_params(table: dict) -> SourceParams:
    """The validated [source] table; an InputError (field `source.KEY`) names what is wrong."""
    name = table.get("type", "sun")
    if not isinstance(name, str) or name not in SOURCE_KINDS:
        raise InputError(f"unknown source type {name!r}", field="source.type", valid=" | ".join(SOURCE_KINDS))
    model = SOURCE_KINDS[name].params
    for key in table:  # a key of another kind would otherwise read as a plain typo
        if key not in model.model_fields:
            others = [f"'{n}'" for n, k in SOURCE_KINDS.items() if key in k.params.model_fields]
            guess = did_you_mean(key, model.model_fields)
            said = (f"{key} applies to type = {' or '.join(others)} only" if others else
                    f"unknown key '{key}'" + (f" (did you mean '{guess}'?)" if guess else ""))
            raise InputError(f"{said}, not to a {name} source", field=f"source.{key}",
                             valid=f"the keys of a {name} source: " + ", ".join(model.model_fields))
    try:
        return model.model_validate(table)
    except ValidationError as exc:
        raise input_error(exc, model, prefix=("source",)) from None


def _sun(p: SunParams, at: Placement) -> SunSource:
    half = 0.5 * math.radians(p.angular_diameter_deg)
    disc = emission_disc(source_direction(p.off_axis_deg, p.azimuth_deg), at.opening_z, at.opening_radius,
                         at.clear_distance, half)
    return SunSource(p.off_axis_deg, p.azimuth_deg, disc, p.angular_diameter_deg, p.limb_darkening,
                     at.wavelength_weights)


def _collimated(p: CollimatedParams, at: Placement) -> CollimatedSource:
    disc = emission_disc(source_direction(p.off_axis_deg, p.azimuth_deg), at.opening_z, at.opening_radius,
                         at.clear_distance)
    return CollimatedSource(p.off_axis_deg, p.azimuth_deg, disc, at.wavelength_weights)


def _object(p: PointParams, at: Placement, radius: float) -> ObjectSource:
    """Centred at height_mm toward azimuth_deg on the plane z_mm (default: the lens's object plane)."""
    z = p.z_mm if p.z_mm is not None else at.object_z
    if z is None:
        raise InputError(f"a {p.type} source needs a plane: the lens has its object at infinity", field="source.z_mm",
                         valid="z_mm (mm, surface 1's vertex at 0, the object side negative), or a lens with a "
                               "finite object distance")
    if z >= 0.0:
        raise InputError(f"the {p.type} source at z = {z:g} mm is not in front of surface 1", field="source.z_mm",
                         valid="a plane in front of the lens, z_mm < 0")
    pupil_z, pupil_radius = at.pupil()
    a = math.radians(p.azimuth_deg)
    centre = (p.height_mm * math.cos(a), p.height_mm * math.sin(a), float(z))
    return ObjectSource(centre, radius, float(at.opening_z), float(at.opening_radius) * 1.02 + 1e-3,
                        float(pupil_z), float(pupil_radius), at.wavelength_weights)


register_source("sun", SunParams, _sun)
register_source("collimated", CollimatedParams, _collimated)
register_source("point", PointParams, lambda p, at: _object(p, at, 0.0))
register_source("disc", DiscParams, lambda p, at: _object(p, at, float(p.radius_mm)))


__all__ = ["Source", "Placement", "SourceParams", "SunParams", "CollimatedParams", "PointParams",
           "DiscParams", "SourceKind", "SOURCE_KINDS", "register_source", "source_params", "SunSource", "CollimatedSource", "ObjectSource", "EmissionDisc", "emission_disc", "source_direction",
           "orthonormal_basis", "entering_fraction", "no_light_enters_reason", "disc_radius_fraction"]
