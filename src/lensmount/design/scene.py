"""Scene files (`scenes/*.toml`) → validated `SceneSpec`. Unknown keys are errors.

A scene file is the test condition: source, detector, effects, extra objects and run length.
The surface treatment (finishes, coatings, which faces get which) is the design's
(`DESIGN/finishes.toml`, design.finishes), shared by all its scenes; `load_scene` joins the two
into the SceneSpec a Scene is built from, and refuses a scene file that still holds them.

```toml
description = "Seed paper case 1: only the 50 µm diaphragm edge scatters"

[source]
type = "sun"                 # "sun" | "collimated" (at infinity) | "point" | "disc" (finite distance)
off_axis_deg = 7.0           # sun, collimated
azimuth_deg = 90.0           # 90 = source displaced toward +y (its light travels toward -y)
angular_diameter_deg = 0.53  # sun only
limb_darkening = false       # sun only
# height_mm = 0.0            # point, disc: centre's distance from the axis (toward azimuth_deg)
# radius_mm = 5.0            # disc only: a Lambertian disc facing the lens
# z_mm = -500.0              # point, disc: default the lens's object plane (finite conjugates)

[detector]
width_mm = 44.5              # width and height: default the size mount.toml's [housing] was built for
height_mm = 44.5
pixels = [600, 600]          # [nx, ny]; default 600 along the longer side, square pixels
# z_mm = 400.0               # default: the prescription's image plane
# spectral_weight = [1.0]    # one per lens wavelength (relative response)

[effects]
scatter = true               # true | false | ["part:NAME", "role:ROLE", "kind:KIND", "finish:NAME", "surface:N", ...]
ghosts = false               # true | false | { order = 2 } (2: two-reflection ghosts, 3: four too)
direct = false
absorption = true            # bulk absorption in the glass (catalogue data); false: lossless glass

[[objects]]                  # extra scene objects beyond the mount
type = "disk"                # disk | rectangle | mesh (STL or STEP file, relative to the scene file)
name = "dust-plate"
centre_mm = [0.0, 0.0, -20.0]
radius_mm = 30.0             # disk; rectangle: width_mm, height_mm; mesh: path
tilt_deg = [0.0, 0.0]        # about x, then about y
finish = "ground-glass"       # a finish of the design (finishes.toml) or a built-in one

[run]
photons = 100_000            # per pass
passes = 32                  # at most this many
seed = 1
target_rel_error = 0.05      # stop at this relative error (std + bias bound; after 8 passes at least)
time_s = 600                 # or after this many seconds of tracing, whichever comes first (the default)
view_map_pitch = 1           # bidirectional: the view map samples blocks of 1 × 1 pixels a pass (4: 16× fewer
                             # backward rays; the total's error barely moves, the image fills in over passes)

[requirement]                # what `lensmount pst` judges the curve by (other commands ignore it)
angles_deg = [0, 10, 30, 85] # increasing, in [0, 90]
pst_max = [1e-2, 1e-4, 1e-6, 1e-7]  # PST limit at each; log-linear between them; angles outside: not judged
```
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, SerializeAsAny, ValidationError, field_validator, model_validator

from lensmount.validation import ReadFromFile, input_error, keys_at, line_of_key, located, parse_toml, read_text
from lensmount.errors import InputError
from lensmount.design.finishes import (TABLES, Finishes, check_coatings, check_finishes, finish_library,
                                       old_layout_error)
from lensmount.physics.interfaces import parse_coating
from lensmount.physics.sources import SourceParams, source_params


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)  # no key takes NaN or inf


DETECTOR_PIXELS_LONG_SIDE = 600


class DetectorSpec(_Strict):
    """Width and height may both be left out: the detector then takes the size the mount's housing
    was built for (`mount.toml [housing] detector_width_mm, detector_height_mm`, filled in by
    `fit_detector_to_housing`). Pixels left out: 600 along the longer side, square pixels."""

    width_mm: float | None = Field(default=None, gt=0.0)
    height_mm: float | None = Field(default=None, gt=0.0)
    pixels: tuple[int, int] | None = None
    z_mm: float | None = None
    spectral_weight: tuple[float, ...] | None = None

    @field_validator("pixels")
    @classmethod
    def _positive(cls, v):
        if v[0] < 1 or v[1] < 1 or v[0] * v[1] > 50_000_000:
            raise ValueError("pixels must be [nx, ny] with nx, ny >= 1 and at most 5e7 pixels")
        return v

    @field_validator("spectral_weight")
    @classmethod
    def _weights(cls, v):
        if v is not None and (any(w < 0 for w in v) or not any(w > 0 for w in v)):
            raise ValueError("spectral_weight must be non-negative with at least one positive value")
        return v

    @model_validator(mode="after")
    def _size(self):
        if (self.width_mm is None) != (self.height_mm is None):
            raise ValueError("give both width_mm and height_mm, or neither (the housing's detector size)")
        return self

    def fitted(self, width_mm: float, height_mm: float) -> "DetectorSpec":
        """This detector with the size given where the file left it out, and its pixels."""
        width = self.width_mm if self.width_mm is not None else width_mm
        height = self.height_mm if self.height_mm is not None else height_mm
        pixels = self.pixels
        if pixels is None:
            pitch = max(width, height) / DETECTOR_PIXELS_LONG_SIDE
            pixels = (max(1, round(width / pitch)), max(1, round(height / pitch)))
        return self.model_copy(update={"width_mm": width, "height_mm": height, "pixels": pixels})


SCATTER_SELECTORS = ("part", "role", "kind", "finish", "surface")


class GhostsSpec(_Strict):
    order: Literal[2, 3] = 2


class EffectsSpec(_Strict):
    """`scatter`: true (every mechanical face scatters with its finish), false (every one absorbs),
    or the faces that scatter as selectors (`part:NAME`, `role:ROLE`, `kind:KIND`, `finish:NAME`,
    the finish the scene gives the face, `surface:N`, a mirror's coated face); every other mechanical
    face ends the path (a mirror face left out reflects specularly only). The
    selectors are checked against the built assembly (`scene.build.check_scatterers`).
    `ghosts`: true (= order 2), false, or `{ order = 2 | 3 }`: order 2 counts the two-reflection
    ghosts, order 3 the four-reflection ones too (three reflections send the light back out of the
    front). `direct`: unscattered light on the detector. `absorption`: the glass's bulk absorption
    along every path (catalogue data); false for lossless references."""

    scatter: bool | tuple[str, ...] = True
    ghosts: bool | GhostsSpec = False
    direct: bool = False
    absorption: bool = True

    @field_validator("scatter")
    @classmethod
    def _selectors(cls, v):
        if isinstance(v, bool):
            return v
        if not v:
            raise ValueError("an empty list selects no face; write scatter = false for no scattering")
        for sel in v:
            prefix, _, value = sel.partition(":")
            if prefix not in SCATTER_SELECTORS or not value:
                raise ValueError(f"scatter selector '{sel}' is not understood: use "
                                 + ", ".join(f'"{p}:{"N" if p == "surface" else "NAME"}"' for p in SCATTER_SELECTORS))
        return v

    @property
    def ghost_order(self) -> int:
        """Ghost order (2: two reflections, 3: four too): 0 with ghosts off."""
        if isinstance(self.ghosts, GhostsSpec):
            return self.ghosts.order
        return 2 if self.ghosts else 0


class RunSpec(_Strict):
    """The run length `simulate` takes when its command line sets none (loop.simulate.stopping): photons
    per pass; at most `passes` passes; the target error when given; never more than time_s seconds of
    tracing (a longer run is a batch job: say so with a larger time_s). `view_map_pitch` is the
    bidirectional view map's (integrators.settings.EstimatorSettings): part of the estimator, so of
    the input hash."""

    photons: int = Field(default=1_000_000, ge=1)
    passes: int = Field(default=32, ge=1)
    seed: int = Field(default=1, ge=0)
    target_rel_error: float | None = Field(default=None, gt=0.0)
    time_s: float = Field(default=600.0, gt=0.0)
    view_map_pitch: int = Field(default=1, ge=1)


class RequirementSpec(_Strict):
    """A point source transmittance requirement: PST at most `pst_max[i]` at `angles_deg[i]`, interpolated
    log-linearly between the listed angles (a straight line on the PST plot's log axis, as PST falls by orders of
    magnitude past the field); an angle outside the listed range has no requirement."""

    angles_deg: tuple[float, ...] = Field(min_length=1)
    pst_max: tuple[float, ...] = Field(min_length=1)

    @model_validator(mode="after")
    def _limits(self):
        if len(self.angles_deg) != len(self.pst_max):
            raise ValueError(f"angles_deg has {len(self.angles_deg)} angles and pst_max {len(self.pst_max)} limits: "
                             "one limit per angle")
        if any(not 0.0 <= a <= 90.0 for a in self.angles_deg) or any(
                b <= a for a, b in zip(self.angles_deg, self.angles_deg[1:])):
            raise ValueError("angles_deg must increase, each in [0, 90] degrees")
        if any(not 0.0 < v < float("inf") for v in self.pst_max):
            raise ValueError("pst_max must be positive and finite (a PST limit)")
        return self

    def limit(self, angle_deg: float) -> float | None:
        """The PST limit at `angle_deg`, log-linear between the listed angles; None outside them."""
        a = self.angles_deg
        if not a[0] <= angle_deg <= a[-1]:
            return None
        return float(10 ** np.interp(angle_deg, a, np.log10(self.pst_max)))


class ObjectSpec(_Strict):
    type: Literal["disk", "rectangle", "mesh"]
    name: str
    centre_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tilt_deg: tuple[float, float] = (0.0, 0.0)
    finish: str = "absorber"
    radius_mm: float | None = Field(default=None, gt=0.0)
    width_mm: float | None = Field(default=None, gt=0.0)
    height_mm: float | None = Field(default=None, gt=0.0)
    path: str | None = None

    @model_validator(mode="after")
    def _dimensions(self):
        need = {"disk": ("radius_mm",), "rectangle": ("width_mm", "height_mm"), "mesh": ("path",)}[self.type]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {self.type} object needs {', '.join(missing)}")
        unused = [k for k in ("radius_mm", "width_mm", "height_mm", "path")
                  if k not in need and getattr(self, k) is not None]
        if unused:  # a rectangle given radius_mm would silently keep its own size
            raise ValueError(f"a {self.type} object takes {', '.join(need)}, not {', '.join(unused)}")
        if self.type == "mesh" and not str(self.path).lower().endswith((".stl", ".step", ".stp")):
            raise ValueError("path must be an .stl, .step or .stp file")
        return self


class SceneSpec(ReadFromFile, _Strict):
    """A validated scene (see the module docstring for every key) with the design's surface treatment
    it is simulated with (`finishes`, `coatings`, `assign`: the design's finishes.toml, joined in by
    `load_scene`; `scene_from_dict` takes them in the table, as scripts and tests build scenes)."""

    description: str = ""
    # One of physics.sources.SOURCES' parameter models, by `type`; dumped with its own keys.
    source: SerializeAsAny[SourceParams]
    detector: DetectorSpec
    effects: EffectsSpec = EffectsSpec()
    coatings: dict[str, str] = Field(default_factory=lambda: {"default": "perfect-ar"})
    finishes: dict[str, dict] = Field(default_factory=dict)
    # No rules: every face keeps its mount finish. (A default of {"*": "absorber"} made adding
    # one rule flip every other face from absorber to its mount finish without a word.)
    assign: dict[str, str] = Field(default_factory=dict)
    objects: tuple[ObjectSpec, ...] = ()
    run: RunSpec = RunSpec()
    requirement: RequirementSpec | None = None
    base_dir: str = Field(default=".", exclude=True)  # folder of the scene file (for object paths)
    _finishes_source: tuple[str | None, str | None] | None = PrivateAttr(None)

    @property
    def finishes_source(self) -> tuple[str | None, str | None]:
        """(file, text) the treatment came from, for errors found in it later (a rule matching no face):
        the design's finishes.toml, or the scene's own when a script gave the tables with the scene."""
        return self._finishes_source or (self.source_file, self.source_text)

    @field_validator("source", mode="before")
    @classmethod
    def _source_kind(cls, v):
        return source_params(v) if isinstance(v, dict) else v

    @field_validator("coatings")
    @classmethod
    def _coatings(cls, v):
        return check_coatings(v)

    def coating_of_surface(self, index0: int, lens_coating: str | None = None, mirror: bool = False):
        """Coating of 0-based surface: the scene's per-surface entry, else the lens file's, else default.
        The default is a glass coating: a mirror without its own keeps its reflectance
        (`physics.interfaces.mirror_reflectance`), so `default = "R=0.01"` for ghosts leaves mirrors alone."""
        key = f"surface-{index0 + 1}"
        if key in self.coatings:
            return parse_coating(self.coatings[key])
        if lens_coating is not None:
            return parse_coating(lens_coating)
        return parse_coating(None if mirror else self.coatings.get("default", "perfect-ar"))


def load_scene(path: str | Path, finishes: Finishes | None = None) -> SceneSpec:
    """Read and validate a scene file, simulated with the design's `finishes` (None: the built-in
    treatment); every problem is an InputError naming the file and field. A scene file holding
    `[finishes]`, `[coatings]` or `[assign]` (the layout before they moved to the design) is refused
    with how to move them."""
    path = Path(path)
    text = read_text(path, "scene file", "a path to a scenes/*.toml file")
    data = parse_toml(text, str(path))
    held = sorted((table for table in TABLES if table in data), key=lambda t: line_of_key(text, t) or 0)
    if held:
        raise old_layout_error(str(path), held).located(str(path), line_of_key(text, held[0]))
    finishes = finishes or Finishes()
    spec = scene_from_dict(data | finishes.tables(), file=str(path), base_dir=str(path.parent), text=text)
    spec._finishes_source = (finishes.source_file, finishes.source_text)
    return spec


def scene_from_dict(data: dict, *, file: str | None = None, base_dir: str = ".", text: str | None = None) -> SceneSpec:
    """Validate a parsed scene table (also what tests and scripts use); `text` is the file's
    text, for line numbers."""
    if "base_dir" in data:
        raise InputError("unknown key 'base_dir'", file=file, field="base_dir", valid=_valid_keys(("base_dir",)))
    try:
        if isinstance(data.get("source"), dict):  # here, not in the validator: pydantic would rewrap its paragraph
            data = {**data, "source": source_params(data["source"])}
        spec = SceneSpec(**data, base_dir=base_dir)
    except ValidationError as exc:
        raise input_error(exc, SceneSpec, file=file, text=text) from None
    except InputError as exc:
        raise located(exc, file, text) from None
    spec._file, spec._text = file, text
    try:
        resolved = check_finishes(spec.finishes, spec.assign, base_dir)
        spec = spec.model_copy(update={"finishes": resolved})  # measured finishes: their tables
        spec._file, spec._text = file, text
        library = finish_library(resolved)
        for k, obj in enumerate(spec.objects):
            if obj.finish not in library:
                raise InputError(f"object '{obj.name}' names undefined finish '{obj.finish}'",
                                 field=f"objects.{k}.finish", valid=", ".join(sorted(library)))
    except InputError as exc:
        raise located(exc, file, text) from None
    return spec


def fit_detector_to_housing(spec: SceneSpec, mount) -> SceneSpec:
    """The scene with its detector sized for the mount's housing where `[detector]` gives no size."""
    housing = mount.housing
    fitted = spec.model_copy(update={"detector": spec.detector.fitted(housing.detector_width_mm,
                                                                      housing.detector_height_mm)})
    fitted._file, fitted._text, fitted._finishes_source = spec._file, spec._text, spec._finishes_source
    return fitted


def _valid_keys(loc) -> str:
    """The keys allowed in the table where the error is."""
    return ", ".join(keys_at(SceneSpec, tuple(loc)))


__all__ = ["SceneSpec", "RequirementSpec", "DetectorSpec", "EffectsSpec", "GhostsSpec", "RunSpec", "ObjectSpec", "load_scene",
           "scene_from_dict"]
