"""mount.toml → MountSpec: the mechanical parameters of a lens mount, validated.

Every table and key is documented in docs/mount-toml.md. Unknown keys are errors
(a misspelt key silently ignored would give the wrong mount). Lengths in mm,
angles in degrees (as everywhere in files).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from lensmount.validation import ReadFromFile, did_you_mean, input_error, line_of_key, parse_toml, read_text
from lensmount.errors import InputError

ContactStyle = Literal["sharp", "tangent"]
KNOWN_KINDS = ("lens", "barrel", "spacer", "retainer", "diaphragm", "vane", "hood", "housing", "baffle")
FINISH_TABLES = ("barrel", "lens_edge", "spacers", "retainer", "diaphragm", "vanes", "hood", "housing")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)  # no key takes NaN or inf


class Barrel(_Strict):
    """The barrel: a stepped bore with seats."""

    wall_mm: float = Field(3.0, gt=0, description="radial wall outside the largest bore")
    radial_clearance_mm: float = Field(0.05, ge=0, description="lens edge to bore, radial")
    lip_mm: float = Field(2.0, gt=0, description="axial thickness of a barrel shoulder or end lip")
    finish: str = "black-anodised"


class LensEdge(_Strict):
    """How lens elements are edged."""

    style: Literal["ground-cylinder", "chamfered"] = "chamfered"
    chamfer_mm: float = Field(0.5, ge=0, description="45° protective chamfer size (style chamfered)")
    allowance_mm: float = Field(2.0, ge=0, description="mechanical minus clear semi-diameter, "
                                "when the lens file gives no mechanical semi-diameter")
    contact_margin_mm: float = Field(0.5, ge=0, description="mechanical contact height above the "
                                     "clear semi-diameter")
    semi_diameter_mm: dict[int, float] = Field(
        default_factory=dict, description="1-based element number → mechanical semi-diameter (mm); "
        "a cemented group takes the largest of its elements")
    flat_faces: list[int] = Field(default_factory=list, description="1-based surface numbers of outer "
                                  "lens faces ground flat from their clear semi-diameter out (a deep face "
                                  "curling toward the diaphragm beside it leaves it room; a thin meniscus gets "
                                  "its flat bevel where needed anyway)")
    stepped_min_edge_mm: float = Field(0.2, gt=0, description="least edge of an outer element of a "
                                       "cemented group that is too thin at the group's rim and is edged "
                                       "to its clear aperture plus a bevel instead (a stepped group, seated "
                                       "on its partner): it carries no seat, the cement holds it")
    allow_vignetting: bool = Field(False, description="an element whose faces cross (or come closer than "
                                   "its least edge) inside the beam of the full field is edged where its glass "
                                   "allows (its edge the [checks] minimum after two chamfers) whatever that "
                                   "vignettes, on-axis rays included; the vignetting per field is in regenerate's "
                                   "notes and check's report. False: the lens is refused when such an edge stops "
                                   "an on-axis ray or more than 10 % of a field's pupil")
    finish: str = "ground-glass"


class Seats(_Strict):
    """What holds each element: the seat on its object side."""

    contact: ContactStyle = "sharp"
    front: Literal["retainer", "shoulder", "bonded"] = Field("retainer", description="what holds the first "
        "element from the object side (bonded: an adhesive bead between its ground edge and the barrel's bore, "
        "nothing on its face: the seat for a lens whose beam reaches its rim, no annulus left for a ring)")
    rear: Literal["retainer", "shoulder", "bonded"] = Field("shoulder", description="what holds the last "
        "element from the image side (as front)")
    default: Literal["spacer", "shoulder"] = "spacer"
    element: dict[int, Literal["spacer", "shoulder", "retainer", "glass"]] = Field(
        default_factory=dict, description="1-based element number → seat on its object side "
        "(retainer: a ring holds it, a barrel shoulder holds the element in front; glass: the "
        "element with the smaller edge rests its rim on the other's face, no part between them)")
    wedge_deg: float = Field(1.0, gt=0, lt=45, description="smallest angle at which a sharp-contact "
                             "end face leaves the glass it touches (no sub-micrometre sliver beside a contact)")
    clearance_mm: float = Field(0.01, gt=0, description="glass to metal where the metal does not hold "
                                "the glass (barrel steps beside a lens edge, a diaphragm next to its stop face)")


class Spacers(_Strict):
    radial_clearance_mm: float = Field(0.02, ge=0, description="spacer outside to bore")
    aperture_margin_mm: float = Field(1.0, ge=0, description="spacer bore above the beam where "
                                      "the spacer meets the diaphragm")
    tube_wall_mm: float = Field(2.0, gt=0, description="radial wall of a long spacer tube "
                                "(long gaps get a tube with end lips and vanes inside)")
    lip_mm: float = Field(2.0, gt=0, description="axial thickness of a long spacer's end lips")
    finish: str = "black-anodised"


class Retainer(_Strict):
    thickness_mm: float = Field(3.0, gt=0, description="axial thickness at the outside")
    finish: str = "black-anodised"


class Diaphragm(_Strict):
    thickness_mm: float = Field(1.0, gt=0)
    land_mm: float = Field(0.05, gt=0, description="axial width of the knife-edge land "
                           "(the seed paper's edge is 0.05 mm)")
    bevel_angle_deg: float = Field(45.0, gt=0, lt=90, description="bevel angle to the plate face")
    bevel_side: Literal["rear", "front"] = "rear"
    finish: str = "black-anodised"


class Vanes(_Strict):
    placement: Literal["line-of-sight", "even"] = Field(
        "line-of-sight", description="hood vanes by the classic construction from the beam envelope "
        "and [hood] exclusion_deg (as many as it takes), or `count` vanes evenly spaced")
    count: int = Field(3, ge=0, description="vanes in the hood (placement = even)")
    positions_mm: list[float] | None = Field(None, description="explicit z of hood vane front faces "
                                             "(assembly frame) instead of automatic placement")
    in_air_gaps: int = Field(1, ge=0, description="vanes in each long spacer tube")
    long_gap_mm: float = Field(40.0, gt=0, description="a spacer at least this long is a tube with vanes")
    aperture_margin_mm: float = Field(0.5, ge=0, description="vane bore above the beam envelope")
    edge_width_mm: float = Field(0.1, gt=0, description="axial width of the inner edge land")
    thickness_mm: float = Field(1.0, gt=0)
    bevel_angle_deg: float = Field(45.0, gt=0, lt=90)
    min_height_mm: float = Field(0.5, ge=0, description="a vane lower than this (radially) is left out")
    finish: str = "black-anodised"


class Hood(_Strict):
    enabled: bool = True
    length_mm: float = Field(100.0, gt=0)
    inner_diameter_mm: float | None = Field(None, gt=0, description="None: beam + margins + 4 mm")
    exclusion_deg: float | None = Field(None, gt=0, lt=90, description="the smallest off-axis angle at "
                                        "which the sun may stand (None: the largest field angle + 5°)")
    wall_mm: float = Field(2.0, gt=0)
    finish: str = "black-anodised"


class Housing(_Strict):
    enabled: bool = True
    detector_width_mm: float = Field(44.5, gt=0)
    detector_height_mm: float = Field(44.5, gt=0)
    detector_clearance_mm: float = Field(2.0, ge=0, description="radial room around the detector corners")
    back_gap_mm: float = Field(5.0, gt=0, description="image plane to the housing's back wall")
    wall_mm: float = Field(3.0, gt=0)
    rear_baffle: bool = Field(False, description="a cold-stop style tube (part rear-baffle, kind baffle) "
                              "from the barrel to the detector whose bore follows the beam")
    rear_baffle_margin_mm: float = Field(0.5, ge=0, description="rear baffle bore above the beam envelope")
    rear_baffle_gap_mm: float = Field(1.0, gt=0, description="rear baffle's back end to the image plane")
    rear_baffle_wall_mm: float = Field(1.0, gt=0, description="thinnest radial wall of the rear baffle "
                                       "(the housing's bore grows to make room)")
    finish: str = "black-anodised"


class Checks(_Strict):
    min_thickness_mm: float = Field(0.3, gt=0, description="every part at least this thick "
                                    "(the diaphragm and vane edge lands excepted)")
    min_radial_clearance_mm: float = Field(0.0, ge=0, description="lens edge to bore")


class Bom(_Strict):
    """The bill of materials written beside the STEP files (bom.csv)."""

    metal: str = Field("aluminium 6061-T6", description="material of every mechanical part")
    metal_density_g_cm3: float = Field(2.70, gt=0)
    glass_density_g_cm3: dict[str, float] = Field(
        default_factory=dict, description="glass name → density (g/cm³); a glass not listed weighs "
        "as N-BK7 (2.51) and the BOM says so")


class Drawing(_Strict):
    """Tolerances on the shop drawings (parts/NAME.svg, .dxf), ± each."""

    diameter_mm: float = Field(0.02, gt=0, description="bores and outside diameters")
    length_mm: float = Field(0.05, gt=0, description="axial lengths and thicknesses")
    land_mm: float = Field(0.01, gt=0, description="width of a knife-edge land (diaphragm, vanes)")
    angle_deg: float = Field(0.5, gt=0, description="bevel angles")


class Tessellation(_Strict):
    linear_tolerance_mm: float = Field(0.05, gt=0)
    angular_tolerance_deg: float = Field(6.0, gt=0, le=45)


Datum = str  # "surface-1" … "surface-N", "image-plane", "barrel-front", "barrel-back" (cad.step_parts.datum_z)


class FaceRule(_Strict):
    """One rule for the faces a user's STEP part leaves without a finish (the first that matches wins).
    Every criterion given must hold; a rule with none matches every face left."""

    finish: str
    part: str | None = Field(None, description="the solid's part name (an assembly's solids are parts)")
    faces: list[int] | None = Field(None, description="STEP face indices (parts/NAME.faces.png numbers them)")
    normal: tuple[float, float, float] | None = Field(None, description="outward normal direction (any length), "
                                                      "assembly frame, at the face's middle")
    within_deg: float = Field(10.0, gt=0, le=180, description="largest angle between the face normal and `normal`")
    r_min_mm: float | None = Field(None, ge=0, description="the whole face (its edges) at least this far "
                                   "from the axis")
    r_max_mm: float | None = Field(None, gt=0, description="the whole face (its edges) at most this far "
                                   "from the axis")


class StepPart(_Strict):
    """A part (or an assembly's parts) read from a STEP file: `[parts.NAME]` (docs/mount-toml.md).

    NAME replaces the generated part of that name (`hood`, `housing`, `barrel`, …) or adds a new one.
    The file's frame is placed by `rotate_deg` (about x, then y, then z) and then `offset_mm` from
    `datum` on the optical axis. Finishes per face: `names` (glob on the STEP face name, then the
    solid's name) > `colours` (face colour, else the solid's) > `layers` > `rules` > `finish`.
    """

    step: str = Field(description="the STEP file, relative to the design folder")
    kind: Literal["barrel", "spacer", "retainer", "diaphragm", "vane", "hood", "housing", "baffle"] | None = Field(
        None, description="part kind (default: the replaced part's, else housing)")
    unit: Literal["mm", "inch"] | None = Field(None, description="the length unit the file must declare "
                                               "(the file's own unit is always used; this guards against "
                                               "an export in the wrong unit)")
    datum: Datum = "surface-1"
    offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotate_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    finish: str = "black-anodised"
    names: dict[str, str] = Field(default_factory=dict, description="glob on a STEP face or solid name → finish")
    colours: dict[str, str] = Field(default_factory=dict, description='"#rrggbb" (sRGB) → finish')
    layers: dict[str, str] = Field(default_factory=dict, description="STEP layer name → finish")
    rules: list[FaceRule] = Field(default_factory=list)
    allow_vignetting: bool = Field(False, description="build even when the part does not clear the "
                                   "beam envelope by the margin (the vignetting per field is noted)")
    beam_margin_mm: float | None = Field(None, ge=0, description="clearance to the beam envelope "
                                         "(default: [vanes] aperture_margin_mm)")

    @field_validator("datum")
    @classmethod
    def _datum(cls, v):
        if v in ("image-plane", "barrel-front", "barrel-back") or re.fullmatch(r"surface-[1-9][0-9]*", v):
            return v
        raise ValueError(f"unknown datum {v!r}; valid: surface-N (N a surface number), image-plane, "
                         "barrel-front, barrel-back")

    @field_validator("colours")
    @classmethod
    def _colours(cls, v):
        for key in v:
            if not re.fullmatch(r"#[0-9a-fA-F]{6}", key):
                raise ValueError(f"colour {key!r} is not #rrggbb")
        return v

    def finish_fields(self, name: str) -> dict[str, str]:
        prefix = f"parts.{name}"
        out = {f"{prefix}.finish": self.finish}
        for table in ("names", "colours", "layers"):
            out |= {f"{prefix}.{table}.{k}": f for k, f in getattr(self, table).items()}
        return out | {f"{prefix}.rules.{k}.finish": r.finish for k, r in enumerate(self.rules)}


class MountSpec(ReadFromFile, _Strict):
    """The whole mount.toml."""

    name: str = "mount"
    barrel: Barrel = Barrel()
    lens_edge: LensEdge = LensEdge()
    seats: Seats = Seats()
    spacers: Spacers = Spacers()
    retainer: Retainer = Retainer()
    diaphragm: Diaphragm = Diaphragm()
    vanes: Vanes = Vanes()
    hood: Hood = Hood()
    housing: Housing = Housing()
    checks: Checks = Checks()
    tessellation: Tessellation = Tessellation()
    bom: Bom = Bom()
    drawing: Drawing = Drawing()
    finishes: dict[str, str] = Field(default_factory=dict, description="part name → finish override")
    templates: dict[str, str] = Field(default_factory=dict, description="part kind → user template .py")
    parts: dict[str, StepPart] = Field(default_factory=dict, description="part name → a part from a STEP file")
    kinds: dict[str, dict[str, Any]] = Field(default_factory=dict, description="part kind a plug-in registers "
                                             "(cad.stages.PART_KINDS) → its parameters, checked by its own model")

    @field_validator("templates")
    @classmethod
    def _kinds(cls, v):
        for k in v:
            if k not in KNOWN_KINDS:
                raise ValueError(f"unknown part kind {k!r}; valid: {', '.join(KNOWN_KINDS)}")
        return v


    def exclusion_deg(self, max_field_deg: float) -> float:
        """The smallest sun angle off the axis: [hood] exclusion_deg, else the largest field + 5°."""
        return float(self.hood.exclusion_deg if self.hood.exclusion_deg is not None else max_field_deg + 5.0)

    def finish_of(self, part: str, default: str) -> str:
        return self.finishes.get(part, default)

    def finish_fields(self) -> dict[str, str]:
        """Every finish the file names: field path ('barrel.finish', 'finishes.vane-2') → finish."""
        out = {f"{table}.finish": getattr(self, table).finish for table in FINISH_TABLES}
        for name, entry in self.parts.items():
            out |= entry.finish_fields(name)
        return out | {f"finishes.{part}": name for part, name in self.finishes.items()}


def check_finish_parts(mount: MountSpec, part_names) -> None:
    """InputError for a `[finishes]` entry naming a part the assembly does not have (it would
    be ignored without a word, leaving the part its table's finish)."""
    parts = sorted(set(part_names))
    for part in mount.finishes:
        if part not in parts:
            field = f"finishes.{part}"
            guess = did_you_mean(part, parts)
            raise InputError(f"no part is named '{part}'" + (f" (did you mean '{guess}'?)" if guess else ""),
                             file=mount.source_file, field=field, line=line_of_key(mount.source_text, field),
                             valid="a part of this assembly: " + ", ".join(parts))


def parse_mount(data: dict, file: str | None = None, text: str | None = None) -> MountSpec:
    """Validate a mount.toml dictionary (`text`: the file's text, for line numbers); raises
    InputError naming the first bad field."""
    try:
        spec = MountSpec.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, MountSpec, file=file, text=text, valid="see docs/mount-toml.md") from None
    vanes = spec.vanes
    if vanes.placement == "line-of-sight" and vanes.positions_mm is None and "count" in vanes.model_fields_set:
        # the construction decides how many hood vanes it takes: a count here would be silently ignored
        raise InputError(f"[vanes] count = {vanes.count} has no effect under placement = \"line-of-sight\" (the "
                         "default): the construction places as many hood vanes as the beam and [hood] "
                         "exclusion_deg need", file=file, field="vanes.count", line=line_of_key(text, "vanes.count"),
                         valid="remove `count`; or set placement = \"even\" to choose the number of hood vanes; "
                               "positions_mm = [] for none")
    spec._file, spec._text = file, text
    return spec


def load_mount(path: str | Path) -> MountSpec:
    """Read and validate mount.toml."""
    path = Path(path)
    text = read_text(path, "mount file", "a readable mount.toml")
    return parse_mount(parse_toml(text, str(path)), file=str(path), text=text)


__all__ = ["MountSpec", "StepPart", "FaceRule", "load_mount", "parse_mount", "ContactStyle", "FINISH_TABLES",
           "check_finish_parts"]
