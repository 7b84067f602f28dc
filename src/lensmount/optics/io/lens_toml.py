"""The project's own lens file, `lens.toml`: reader and writer.

Format (documented for users in docs/lens-toml.md; unknown keys are errors):

    name = "Double Gauss 360 mm f/7"
    aperture = { f_number = 7.0 }          # or { entrance_pupil_diameter = 51.43 } (mm)
    clear_aperture_margin_mm = 0.0         # added to automatic clear semi-diameters
    glass_catalogs = ["glass/vendor.agf"]  # optional: Zemax .agf catalogues (paths from this file's
                                           # folder), searched for a material name before the built-in ones

    [wavelengths]
    values_um = [0.4861327, 0.5875618, 0.6562725]
    weights = [1.0, 1.0, 1.0]              # optional, default 1 each
    primary = 2                            # 1-based, default the middle one

    [field]
    angles_deg = [0.0, 3.5, 5.0]           # object at infinity, field angles in degrees

    [[surface]]                            # one per surface, from the object side
    radius = 202.328568                    # mm; "inf" or omitted = plane; or curvature = 1/mm
    thickness = 31.5                       # mm to the next surface (last: to the image plane)
    material = "N-SSK2"                    # after the surface; AIR by default
    conic = 0.0                            # optional
    aspheric = [0.0, 0.0]                  # optional even-asphere A4, A6, ... (mm^-3, mm^-5, ...)
    qtype = { form = "qcon", norm_radius = 27.0, coefficients = [0.01, -0.002] }
                                           # optional Forbes Q-type departure on the base conic: form
                                           # "qbfs" or "qcon", normalisation radius (mm), a_0, a_1, ... (mm)
    clear_semi_diameter = 45.0             # optional; omitted = automatic
    mechanical_semi_diameter = 48.0        # optional
    stop = true                            # exactly one surface
    coating = "perfect-ar"                 # optional
    comment = "element 1"                  # optional

Staged like the Zemax reader: TOML text -> pydantic model (`LensFile`) -> Prescription.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from lensmount.atomic import write_text
from lensmount.validation import keys_at, line_of_key, parse_toml
from lensmount.errors import InputError
from lensmount.optics.glass import resolve_glass
from lensmount.optics.io.agf import register_catalogue
from lensmount.optics.prescription import AIR, Aperture, Prescription, Surface
from lensmount.optics.qtype import QType


_INF_WORDS = ("inf", "+inf", "infinity", "+infinity", "-inf", "-infinity", "plane", "flat")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)  # only a radius may be inf


class ApertureModel(_Strict):
    f_number: float | None = Field(default=None, gt=0)
    entrance_pupil_diameter: float | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _exactly_one(self):
        if (self.f_number is None) == (self.entrance_pupil_diameter is None):
            raise ValueError("give exactly one of f_number or entrance_pupil_diameter")
        return self


class WavelengthsModel(_Strict):
    values_um: list[float] = Field(min_length=1)
    weights: list[float] | None = None
    primary: int | None = None

    @field_validator("values_um")
    @classmethod
    def _positive(cls, v):
        if any(not (0.1 <= w <= 20.0) for w in v):
            raise ValueError("wavelengths must lie between 0.1 and 20 µm")
        return v

    @model_validator(mode="after")
    def _consistent(self):
        if self.weights is not None:
            if len(self.weights) != len(self.values_um):
                raise ValueError("weights must have one entry per wavelength")
            if any(w < 0 for w in self.weights) or sum(self.weights) <= 0:
                raise ValueError("weights must be >= 0 and not all zero")
        if self.primary is not None and not 1 <= self.primary <= len(self.values_um):
            raise ValueError(f"primary must be a 1-based index between 1 and {len(self.values_um)}")
        return self


class FieldModel(_Strict):
    angles_deg: list[float] = Field(min_length=1)

    @field_validator("angles_deg")
    @classmethod
    def _range(cls, v):
        if any(not (abs(a) < 89.0) for a in v):
            raise ValueError("field angles must lie strictly between -89 and 89 degrees")
        return v


class QTypeModel(_Strict):
    """A Forbes Q-type departure (lensmount.optics.qtype)."""

    form: Literal["qbfs", "qcon"]
    norm_radius: float = Field(gt=0)
    coefficients: list[float] = Field(min_length=1)

    @field_validator("norm_radius", "coefficients")
    @classmethod
    def _finite(cls, v):
        if not all(math.isfinite(x) for x in (v if isinstance(v, list) else [v])):
            raise ValueError("must be finite numbers")
        return v

    def to_qtype(self) -> QType:
        return QType(self.form, self.norm_radius, tuple(self.coefficients))


class SurfaceModel(_Strict):
    radius: Union[Annotated[float, Field(allow_inf_nan=True)], str, None] = None
    curvature: float | None = None
    thickness: float
    material: str = AIR
    conic: float = 0.0
    aspheric: list[float] = Field(default_factory=list)
    qtype: QTypeModel | None = None
    clear_semi_diameter: float | None = Field(default=None, gt=0)
    mechanical_semi_diameter: float | None = Field(default=None, gt=0)
    stop: bool = False
    coating: str | None = None
    comment: str | None = None

    @field_validator("radius")
    @classmethod
    def _radius(cls, v):
        if isinstance(v, str):
            if v.strip().lower() not in _INF_WORDS:
                raise ValueError('radius must be a number of mm or "inf" for a plane')
            return math.inf
        if v is not None and v == 0:
            raise ValueError('radius 0 is not a surface; use "inf" (or omit it) for a plane')
        if v is not None and math.isnan(v):
            raise ValueError('radius nan is not a number of mm')
        return v

    @field_validator("thickness", "conic")
    @classmethod
    def _finite(cls, v):
        if not math.isfinite(v):
            raise ValueError("must be a finite number")
        return v

    @model_validator(mode="after")
    def _one_of(self):
        if self.radius is not None and self.curvature is not None:
            raise ValueError("give radius or curvature, not both")
        return self

    def to_surface(self) -> Surface:
        if self.curvature is not None:
            radius = math.inf if self.curvature == 0 else 1.0 / self.curvature
        else:
            radius = math.inf if self.radius is None else float(self.radius)
        return Surface(radius=radius, thickness=self.thickness, material=self.material.strip(),
                       conic=self.conic, aspheric=tuple(self.aspheric),
                       qtype=None if self.qtype is None else self.qtype.to_qtype(),
                       clear_semi_diameter=self.clear_semi_diameter,
                       mechanical_semi_diameter=self.mechanical_semi_diameter,
                       is_stop=self.stop, coating=self.coating)


class LensFile(_Strict):
    name: str = "lens"
    description: str | None = None
    units: Literal["mm"] = "mm"
    aperture: ApertureModel
    clear_aperture_margin_mm: float = Field(default=0.0, ge=0)
    wavelengths: WavelengthsModel = WavelengthsModel(values_um=[0.5875618])
    field: FieldModel = FieldModel(angles_deg=[0.0])
    glass_catalogs: list[str] = Field(default_factory=list)
    surface: list[SurfaceModel] = Field(min_length=1)

    def to_prescription(self, folder: Path = Path(".")) -> Prescription:
        wl = self.wavelengths
        weights = wl.weights if wl.weights is not None else [1.0] * len(wl.values_um)
        primary = (wl.primary - 1) if wl.primary is not None else len(wl.values_um) // 2
        ap = self.aperture
        aperture = (Aperture("fno", ap.f_number) if ap.f_number is not None
                    else Aperture("epd", ap.entrance_pupil_diameter))
        catalogues = tuple(str((folder / c).resolve()) for c in self.glass_catalogs)
        user = tuple(register_catalogue(c) for c in catalogues)
        surfaces = []
        for s in self.surface:
            surface = s.to_surface()
            found = resolve_glass(surface.material, user) if user and ":" not in surface.material else None
            if found is not None and found.material.split(":")[0] in user:
                surface = replace(surface, material=found.material)
            surfaces.append(surface)
        return Prescription(
            surfaces=tuple(surfaces), aperture=aperture,
            wavelengths_um=tuple(wl.values_um), wavelength_weights=tuple(weights),
            primary_wavelength=primary, field_angles_deg=tuple(self.field.angles_deg), name=self.name,
            glass_catalogs=catalogues)


_VALID = {
    "aperture": "aperture = { f_number = 7.0 } or aperture = { entrance_pupil_diameter = 51.43 } (mm, > 0)",
    "radius": 'a radius in mm (non-zero), "inf" for a plane, or curvature = 1/mm instead',
    "thickness": "a finite thickness in mm",
    "clear_semi_diameter": "a semi-diameter in mm > 0, or omit it for an automatic one",
    "mechanical_semi_diameter": "a semi-diameter in mm > 0, or omit it",
    "values_um": "a list of wavelengths in µm, e.g. [0.4861327, 0.5875618, 0.6562725]",
    "angles_deg": "a list of field angles in degrees, e.g. [0.0, 3.5, 5.0]",
    "surface": "one or more [[surface]] tables",
}


def parse_lens_toml(text: str, file: str = "lens.toml", glass_catalogs=()) -> tuple[Prescription, float]:
    """Parse lens.toml text. Returns (prescription, clear-aperture margin in mm).
    glass_catalogs: .agf files searched after the file's own `glass_catalogs` (--glass-catalog)."""
    data = parse_toml(text, file, valid="TOML syntax (https://toml.io), e.g. key = value, [[surface]] tables")
    try:
        model = LensFile.model_validate(data)
    except ValidationError as exc:
        raise _input_error(exc, text, file) from None
    folder = Path(file).parent
    for k, rel in enumerate(model.glass_catalogs):
        if not (folder / rel).is_file():
            raise InputError(f"glass catalogue {rel!r} not found", file=file, field=f"glass_catalogs[{k + 1}]",
                             line=line_of_field(text, "glass_catalogs"),
                             valid="a Zemax .agf file, its path relative to the lens.toml's folder")
    extra = [str(Path(c).resolve()) for c in glass_catalogs]
    model = model.model_copy(update={"glass_catalogs": model.glass_catalogs + extra})
    return model.to_prescription(folder), model.clear_aperture_margin_mm


def read_lens_toml(path, glass_catalogs=()) -> tuple[Prescription, float]:
    """Read a lens.toml file (see module docstring)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("file not found", file=str(path), valid="a path to an existing lens.toml or .zmx") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the file ({exc})", file=str(path), valid="a readable UTF-8 TOML file") from None
    return parse_lens_toml(text, str(path), glass_catalogs)


def _field_path(loc) -> tuple[str, int | None, str | None]:
    """pydantic loc -> ('surface[3].thickness', surface number (1-based) or None, last key)."""
    parts, surface_no, last = [], None, None
    for i, item in enumerate(loc):
        if isinstance(item, int):
            if parts and parts[-1] == "surface":
                surface_no = item + 1
            parts[-1] = f"{parts[-1]}[{item + 1}]" if parts else f"[{item + 1}]"
        elif item in ("function-after", "float", "str", "none") or "[" in str(item):
            continue  # union branch names pydantic inserts
        else:
            parts.append(str(item))
            last = str(item)
    return ".".join(parts), surface_no, last


def _input_error(exc: ValidationError, text: str, file: str) -> InputError:
    err = exc.errors()[0]
    field, _, last = _field_path(err["loc"])
    line = line_of_field(text, field)
    if err["type"] == "extra_forbidden":
        valid = "known keys: " + ", ".join(keys_at(LensFile, err["loc"]))
        return InputError(f"unknown key '{last}'", file=file, field=field, line=line, valid=valid)
    if err["type"] == "missing":
        return InputError(f"required key '{last}' is missing", file=file, field=field, line=line,
                          valid=_VALID.get(last or "", "see docs/lens-toml.md"))
    msg = err["msg"].removeprefix("Value error, ")
    return InputError(msg, file=file, field=field, line=line, valid=_VALID.get(last or "", "see docs/lens-toml.md"))


def line_of_field(text: str, field: str) -> int | None:
    """Line of a field path such as 'surface[3].thickness' (1-based surface numbers, as errors
    show them) in lens.toml text: the shared `validation.line_of_key`, which follows tables."""
    path = re.sub(r"\[(\d+)\]", lambda m: f".{int(m.group(1)) - 1}", field or "")
    return line_of_key(text, path)


# ----------------------------------------------------------------------------- writer


def _num(x: float) -> str:
    if math.isinf(x):
        return '"inf"' if x > 0 else '"-inf"'
    return repr(float(x))


def format_lens_toml(prescription: Prescription, margin_mm: float = 0.0, header: str | None = None) -> str:
    """lens.toml text for a prescription (round-trips through parse_lens_toml)."""
    p = prescription
    if p.has_mirrors or p.finite_object:
        raise InputError("lens.toml holds refractive lenses with the object at infinity; this lens has "
                         + ("a mirror" if p.has_mirrors else "a finite object distance"),
                         valid="keep the .zmx as the lens file (lensmount reads it directly)")
    if p.vignetting and any(s.clear_semi_diameter is None for s in p.surfaces):
        raise InputError("lens.toml has no vignetting factors, and this lens leaves semi-diameters to a "
                         "vignetted beam", valid="the lens with its clear semi-diameters filled in (load_lens)")
    out = []
    if header:
        out += [f"# {ln}".rstrip() for ln in header.splitlines()]
        out.append("")
    out.append(f"name = {_str(p.name)}")
    if p.aperture.kind == "fno":
        out.append(f"aperture = {{ f_number = {_num(p.aperture.value)} }}")
    else:
        out.append(f"aperture = {{ entrance_pupil_diameter = {_num(p.aperture.value)} }}")
    if margin_mm:
        out.append(f"clear_aperture_margin_mm = {_num(margin_mm)}")
    if p.glass_catalogs:
        out.append("glass_catalogs = [" + ", ".join(_str(c) for c in p.glass_catalogs) + "]")
    out += ["", "[wavelengths]",
            "values_um = [" + ", ".join(_num(w) for w in p.wavelengths_um) + "]",
            "weights = [" + ", ".join(_num(w) for w in p.wavelength_weights) + "]",
            f"primary = {p.primary_wavelength + 1}",
            "", "[field]",
            "angles_deg = [" + ", ".join(_num(a) for a in p.field_angles_deg) + "]"]
    for i, s in enumerate(p.surfaces):
        out += ["", f"[[surface]]  # {i + 1}"]
        if not math.isinf(s.radius):
            out.append(f"radius = {_num(s.radius)}")
        else:
            out.append('radius = "inf"')
        out.append(f"thickness = {_num(s.thickness)}")
        out.append(f"material = {_str(s.material)}")
        if s.conic:
            out.append(f"conic = {_num(s.conic)}")
        if any(s.aspheric):
            out.append("aspheric = [" + ", ".join(_num(a) for a in s.aspheric) + "]")
        if s.qtype is not None:
            q = s.qtype
            out.append(f"qtype = {{ form = {_str(q.form)}, norm_radius = {_num(q.norm_radius)}, coefficients = ["
                       + ", ".join(_num(a) for a in q.coefficients) + "] }")
        if s.clear_semi_diameter is not None:
            out.append(f"clear_semi_diameter = {_num(s.clear_semi_diameter)}")
        if s.mechanical_semi_diameter is not None:
            out.append(f"mechanical_semi_diameter = {_num(s.mechanical_semi_diameter)}")
        if s.is_stop:
            out.append("stop = true")
        if s.coating:
            out.append(f"coating = {_str(s.coating)}")
    return "\n".join(out) + "\n"


def write_lens_toml(prescription: Prescription, path, margin_mm: float = 0.0, header: str | None = None) -> Path:
    """Write lens.toml atomically (temp file in the same folder, then rename)."""
    path = Path(path)
    text = format_lens_toml(prescription, margin_mm, header)
    write_text(path, text)
    return path


def _str(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


__all__ = ["LensFile", "line_of_field", "parse_lens_toml", "read_lens_toml", "format_lens_toml", "write_lens_toml"]
