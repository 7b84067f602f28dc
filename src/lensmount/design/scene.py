"""Scene files (`scenes/*.toml`) → validated `SceneSpec`. Unknown keys are errors.

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

[coatings]
default = "perfect-ar"       # perfect-ar | uncoated | mgf2-quarter-wave | R=0.01
# surface-3 = "uncoated"     # per surface, 1-based as in the lens file

[finishes]
edge-lambert-10 = { model = "lambertian", reflectance = 0.10 }

[assign]                     # part: > role: > kind: > finish: > "*"; no rule: the mount's finish;
                             # "surface:N" = a mirror's coated face (its scatter on top of R)
"*" = "absorber"
"role:diaphragm-edge" = "edge-lambert-10"

[[objects]]                  # extra scene objects beyond the mount
type = "disk"                # disk | rectangle | mesh (STL or STEP file, relative to the scene file)
name = "dust-plate"
centre_mm = [0.0, 0.0, -20.0]
radius_mm = 30.0             # disk; rectangle: width_mm, height_mm; mesh: path
tilt_deg = [0.0, 0.0]        # about x, then about y
finish = "ground-glass"

[run]
photons = 1_000_000
passes = 32
seed = 1
target_rel_error = 0.05
```
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from lensmount.validation import (ReadFromFile, did_you_mean, input_error, keys_at, line_of_key, located, parse_toml,
                                  read_text)
from lensmount.errors import InputError
from lensmount.design.finishes import check_rules, finish_library
from lensmount.physics.interfaces import parse_coating


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SourceSpec(_Strict):
    type: Literal["sun", "collimated", "point", "disc"] = "sun"
    off_axis_deg: float | None = Field(default=None, ge=0.0, le=180.0)
    azimuth_deg: float = 90.0
    angular_diameter_deg: float = Field(default=0.53, ge=0.0, le=10.0)
    limb_darkening: bool = False
    height_mm: float = Field(default=0.0, ge=0.0)
    radius_mm: float | None = Field(default=None, gt=0.0)
    z_mm: float | None = None

    @property
    def at_infinity(self) -> bool:
        return self.type in ("sun", "collimated")

    @model_validator(mode="after")
    def _keys_of_the_type(self):
        sun_only = {"limb_darkening", "angular_diameter_deg"} & self.model_fields_set
        finite_only = {"height_mm", "radius_mm", "z_mm"} & self.model_fields_set
        if self.at_infinity:
            if self.off_axis_deg is None:
                raise ValueError(f"type = '{self.type}' (a source at infinity) needs off_axis_deg")
            if self.type == "collimated" and sun_only:  # would be ignored without a word
                raise ValueError(f"{', '.join(sorted(sun_only))} applies to type = 'sun' only")
            if finite_only:
                raise ValueError(f"{', '.join(sorted(finite_only))} applies to type = 'point' or 'disc' only "
                                 "(a source at a finite distance)")
            return self
        wrong = sun_only | ({"off_axis_deg"} & self.model_fields_set)
        if wrong:
            raise ValueError(f"{', '.join(sorted(wrong))} applies to sources at infinity (sun, collimated); "
                             f"a {self.type} source sits at height_mm on its plane z_mm")
        if self.type == "disc" and self.radius_mm is None:
            raise ValueError("a disc source needs radius_mm")
        if self.type == "point" and self.radius_mm is not None:
            raise ValueError("radius_mm applies to type = 'disc' only (a point has none)")
        return self


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
    photons: int = Field(default=1_000_000, ge=1)
    passes: int = Field(default=32, ge=1)
    seed: int = Field(default=1, ge=0)
    target_rel_error: float | None = Field(default=None, gt=0.0)


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
    """A validated scene file (see the module docstring for every key)."""

    description: str = ""
    source: SourceSpec
    detector: DetectorSpec
    effects: EffectsSpec = EffectsSpec()
    coatings: dict[str, str] = Field(default_factory=lambda: {"default": "perfect-ar"})
    finishes: dict[str, dict] = Field(default_factory=dict)
    # No rules: every face keeps its mount finish. (A default of {"*": "absorber"} made adding
    # one rule flip every other face from absorber to its mount finish without a word.)
    assign: dict[str, str] = Field(default_factory=dict)
    objects: tuple[ObjectSpec, ...] = ()
    run: RunSpec = RunSpec()
    base_dir: str = Field(default=".", exclude=True)  # folder of the scene file (for object paths)

    @field_validator("coatings")
    @classmethod
    def _coatings(cls, v):
        for key, name in v.items():
            if key != "default" and not (key.startswith("surface-") and key[8:].isdigit() and int(key[8:]) >= 1):
                raise ValueError(f"coating key '{key}' must be 'default' or 'surface-N' (N >= 1)")
            parse_coating(name, field=f"coatings.{key}")
        return v

    def coating_of_surface(self, index0: int, lens_coating: str | None = None, mirror: bool = False):
        """Coating of 0-based surface: the scene's per-surface entry, else the lens file's, else default.
        The default is a glass coating: a mirror without its own keeps its reflectance
        (`trace.interfaces.mirror_reflectance`), so `default = "R=0.01"` for ghosts leaves mirrors alone."""
        key = f"surface-{index0 + 1}"
        if key in self.coatings:
            return parse_coating(self.coatings[key])
        if lens_coating is not None:
            return parse_coating(lens_coating)
        return parse_coating(None if mirror else self.coatings.get("default", "perfect-ar"))


def load_scene(path: str | Path) -> SceneSpec:
    """Read and validate a scene file; every problem is an InputError naming the file and field."""
    path = Path(path)
    text = read_text(path, "scene file", "a path to a scenes/*.toml file")
    data = parse_toml(text, str(path))
    return scene_from_dict(data, file=str(path), base_dir=str(path.parent), text=text)


def scene_from_dict(data: dict, *, file: str | None = None, base_dir: str = ".", text: str | None = None) -> SceneSpec:
    """Validate a parsed scene table (also what tests and scripts use); `text` is the file's
    text, for line numbers."""
    if "base_dir" in data:
        raise InputError("unknown key 'base_dir'", file=file, field="base_dir", valid=_valid_keys(("base_dir",)))
    try:
        spec = SceneSpec(**data, base_dir=base_dir)
    except ValidationError as exc:
        raise input_error(exc, SceneSpec, file=file, text=text) from None
    except InputError as exc:
        raise located(exc, file, text) from None
    spec._file, spec._text = file, text
    library = finish_library(spec.finishes)
    try:
        from lensmount.physics.bsdf import make_bsdf

        for name, params in spec.finishes.items():
            params = dict(params)
            if "model" not in params:
                raise InputError(f"finish '{name}' has no model", field=f"finishes.{name}.model",
                                 valid="absorber, lambertian, gaussian, abg, harvey, mirror, tabulated")
            if params["model"] == "tabulated" and "file" in params:
                params = _measured_table(name, params, base_dir)
                spec.finishes[name] = dict(params)  # the Scene gets the table, not the file name
            try:
                make_bsdf(params.pop("model"), **params)
            except InputError as exc:
                raise InputError(exc.detail, field=f"finishes.{name}.{exc.field or 'model'}", valid=exc.valid) from None
        check_rules(spec.assign, library)
        for k, obj in enumerate(spec.objects):
            if obj.finish not in library:
                raise InputError(f"object '{obj.name}' names undefined finish '{obj.finish}'",
                                 field=f"objects.{k}.finish", valid=", ".join(sorted(library)))
    except InputError as exc:
        raise located(exc, file, text) from None
    return spec


def _measured_table(name: str, params: dict, base_dir: str) -> dict:
    """`{ model = "tabulated", file = "paint.bsdf" }` → the model with the measurement's table."""
    from lensmount.design.brdf_data import read_brdf
    from lensmount.physics.bsdf.tabulated import measured_profile

    extra = sorted(set(params) - {"model", "file"})
    if extra:
        raise InputError(f"a measured finish takes its values from its file, not from '{extra[0]}'",
                         field=f"finishes.{name}.{extra[0]}", valid='model = "tabulated", file = "DATA.bsdf|csv"')
    path = Path(base_dir) / str(params["file"])
    try:
        rho, brdf = measured_profile(*read_brdf(path))
    except InputError as exc:
        raise InputError(f"{exc.detail} (measured BRDF {path})", field=f"finishes.{name}.file",
                         valid=exc.valid) from None
    return {"model": "tabulated", "rho": rho.tolist(), "brdf": brdf.tolist()}


def fit_detector_to_housing(spec: SceneSpec, mount) -> SceneSpec:
    """The scene with its detector sized for the mount's housing where `[detector]` gives no size."""
    housing = mount.housing
    fitted = spec.model_copy(update={"detector": spec.detector.fitted(housing.detector_width_mm,
                                                                      housing.detector_height_mm)})
    fitted._file, fitted._text = spec._file, spec._text
    return fitted


def check_mount_finishes(spec: SceneSpec, mount) -> None:
    """InputError (naming mount.toml's field and line) for a finish the mount file gives that
    the scene does not define.

    Defined: the built-in library, the scene's `[finishes]`, and names the scene's `finish:`
    rules re-assign (a mount finish may be a label the scene maps). A misspelt finish would
    otherwise absorb silently wherever no scene rule covers it. Needs no geometry, so it runs
    before the regenerate.
    """
    library = finish_library(spec.finishes)
    labels = {key.partition(":")[2] for key in spec.assign if key.startswith("finish:")}
    defined = sorted(set(library) | labels)
    for field, name in mount.finish_fields().items():
        if name not in defined:
            guess = did_you_mean(name, defined)
            raise InputError(f"finish '{name}' is not defined" + (f" (did you mean '{guess}'?)" if guess else ""),
                             file=mount.source_file, field=field, line=line_of_key(mount.source_text, field),
                             valid="a defined finish: " + ", ".join(defined)
                                   + "; or define it in the scene's [finishes]")


def _valid_keys(loc) -> str:
    """The keys allowed in the table where the error is."""
    return ", ".join(keys_at(SceneSpec, tuple(loc)))


__all__ = ["SceneSpec", "SourceSpec", "DetectorSpec", "EffectsSpec", "GhostsSpec", "RunSpec", "ObjectSpec", "load_scene",
           "scene_from_dict", "check_mount_finishes"]
