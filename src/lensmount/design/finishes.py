"""Finishes: named surface treatments mapped to BSDF models, and the rules that assign them to faces.

They are part of the design, not of a scene: the design folder's `finishes.toml` holds the
finishes, the coatings and which faces get which, shared by every scene of the design (a
scene is the test condition: source, detector, effects, run length). So a paint change is a
design revision `compare` judges, and a scene file that still carries them is refused with
how to move them (`old_layout_error`).

```toml
# DESIGN/finishes.toml (every table optional; no file: the built-in finishes, the mount's
# own finish per part, perfect-ar coatings)
[finishes]                   # add to or override the built-in library
black-paint = { model = "lambertian", reflectance = 0.05 }
# measured = { model = "tabulated", file = "paint.bsdf" }   # relative to the design folder

[coatings]
default = "perfect-ar"       # perfect-ar | uncoated | mgf2-quarter-wave | R=0.01
# surface-3 = "uncoated"     # per surface, 1-based as in the lens file

[assign]
"*" = "black-paint"
"role:diaphragm-edge" = "absorber"
```

Built-in library (`[finishes]` adds to or overrides it):

| finish           | model                                   |
|------------------|-----------------------------------------|
| `absorber`       | absorber (ends every path)              |
| `black-anodised` | lambertian, reflectance 0.05            |
| `ground-glass`   | lambertian, reflectance 0.10            |
| `mirror`         | mirror, reflectance 1                   |

Assignment (`[assign]`), most specific wins:
`part:NAME` > `role:ROLE` > `kind:KIND` > `finish:NAME` (the finish the mount file gave the face)
> `"*"`. A face the mount file finished face by face (a STEP part's `names`, `colours`, `layers`
or `rules`: `FaceTag.assigned`) is more specific than all of them: it keeps that finish, which only a
`finish:NAME` rule (a definition of the name, not a choice of faces) re-maps. A face matched by no
rule keeps the finish its mount file gave it, which must be defined (an undefined one is an error,
never a silent absorber); a rule that matches no face is an error, and one that decides no face (every
face it selects has a more specific assignment) a warning the run prints (scene.build). Optical faces are never assigned a finish (the tracer refracts
there), except a mirror's coated face by `"surface:N"` (N its 1-based surface number): that
finish is the scatter on top of the specular reflection (micro-roughness, dust). Only the rule
naming the surface reaches it: `"*"` or `part:` rules meant for the blank and the cells would
otherwise turn every mirror of an existing scene into a 5 % Lambertian one.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import ConfigDict, Field, ValidationError, field_validator

from lensmount.design.brdf_data import read_brdf
from lensmount.errors import InputError
from lensmount.mesh import FaceTag
from lensmount.physics.interfaces import parse_coating
from lensmount.validation import ReadFromFile, did_you_mean, input_error, line_of_key, located, parse_toml, read_text

FINISHES_NAME = "finishes.toml"
TABLES = ("finishes", "coatings", "assign")

BUILTIN_FINISHES: dict[str, dict] = {
    "absorber": {"model": "absorber"},
    "black-anodised": {"model": "lambertian", "reflectance": 0.05},
    "ground-glass": {"model": "lambertian", "reflectance": 0.10},
    "mirror": {"model": "mirror", "reflectance": 1.0},
}

_PRIORITY = ("part", "role", "kind", "finish")
RULE_FORMS = ('"*", "part:NAME", "role:ROLE", "kind:KIND", "finish:NAME" or "surface:N" '
              "(a mirror's coated face)")


def surface_rule(surface_index: int) -> str:
    """The rule key naming the coated face of mirror surface `surface_index` (0-based): "surface:N", N 1-based."""
    return f"surface:{surface_index + 1}"


def finish_library(overrides: dict[str, dict] | None = None) -> dict[str, dict]:
    """The built-in finishes updated with the scene's definitions (name -> {model, params...})."""
    lib = {k: dict(v) for k, v in BUILTIN_FINISHES.items()}
    for name, spec in (overrides or {}).items():
        lib[name] = dict(spec)
    return lib


def check_rules(assign: dict[str, str], library: dict[str, dict], *, file: str | None = None) -> None:
    """InputError for a malformed rule key or a rule naming an undefined finish."""
    for key, finish in assign.items():
        if key != "*":
            prefix, _, value = key.partition(":")
            if prefix == "surface" and not (value.isdigit() and int(value) >= 1):
                raise InputError(f"assignment rule '{key}' does not name a surface number", file=file,
                                 field=f"assign.{key}", valid='"surface:N", N the 1-based number of a mirror surface')
            if prefix not in _PRIORITY + ("surface",) or not value:
                raise InputError(f"assignment rule '{key}' is not understood", file=file, field=f"assign.{key}",
                                 valid=RULE_FORMS)
        if finish not in library:
            raise InputError(f"assignment '{key}' names undefined finish '{finish}'", file=file,
                             field=f"assign.{key}", valid=", ".join(sorted(library)))


def deciding_rule(tag: FaceTag, assign: dict[str, str]) -> str | None:
    """The `[assign]` key that gives a face tag its finish (None: the face keeps its mount finish).
    A face the mount file finished face by face is reached by `finish:NAME` only."""
    if tag.role == "optical":
        key = surface_rule(tag.surface) if tag.surface >= 0 else None
        return key if key in assign else None
    for prefix in ("finish",) if tag.assigned else _PRIORITY:
        key = f"{prefix}:{getattr(tag, prefix)}"
        if key in assign:
            return key
    return "*" if "*" in assign and not tag.assigned else None


def finish_of(tag: FaceTag, assign: dict[str, str], library: dict[str, dict]) -> str | None:
    """The finish name for a face tag; for an optical face the `surface:N` rule's finish, else None
    (whether surface N is a mirror is `scene.build.check_rules_match`'s to say)."""
    key = deciding_rule(tag, assign)
    if key is not None:
        return assign[key]
    if tag.role == "optical":
        return None
    if tag.finish not in library:  # never absorb silently: a misspelt mount finish would read as black
        raise InputError(f"part '{tag.part}' has the finish '{tag.finish}' from its mount file, which is not defined, "
                         "and no [assign] rule covers it", field="assign",
                         valid="a defined finish in the mount file (" + ", ".join(sorted(library))
                               + "), a [finishes] entry of that name, or an [assign] rule for the part")
    return tag.finish


def check_coatings(coatings: dict[str, str]) -> dict[str, str]:
    """ValueError for a key that is not 'default' or 'surface-N', InputError for an unknown coating."""
    for key, name in coatings.items():
        if key != "default" and not (key.startswith("surface-") and key[8:].isdigit() and int(key[8:]) >= 1):
            raise ValueError(f"coating key '{key}' must be 'default' or 'surface-N' (N >= 1)")
        parse_coating(name, field=f"coatings.{key}")
    return coatings


def check_finishes(finishes: dict[str, dict], assign: dict[str, str], base_dir: str | Path) -> dict[str, dict]:
    """InputError for a finish whose model or parameters are not valid, or a rule naming an undefined
    finish; the finishes with every measured one's file read into its table (relative to base_dir)."""
    from lensmount.physics.bsdf import BSDFS, make_bsdf  # lazy: keeps lensmount --help from loading the BSDF models

    resolved = {}
    for name, params in finishes.items():
        params = dict(params)
        if "model" not in params:
            raise InputError(f"finish '{name}' has no model", field=f"finishes.{name}.model",
                             valid=", ".join(BSDFS.names()))
        if params["model"] == "tabulated" and "file" in params:
            params = _measured_table(name, params, base_dir)
        resolved[name] = dict(params)  # the Scene gets the table, not the file name
        try:
            make_bsdf(params.pop("model"), **params)
        except InputError as exc:
            raise InputError(exc.detail, field=f"finishes.{name}.{exc.field or 'model'}", valid=exc.valid) from None
    check_rules(assign, finish_library(resolved))
    return resolved


def _measured_table(name: str, params: dict, base_dir: str | Path) -> dict:
    """`{ model = "tabulated", file = "paint.bsdf" }` → the model with the measurement's table."""
    # lazy: keeps lensmount --help from loading the BSDF models (~0.2 s)
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


class Finishes(ReadFromFile):
    """A design's surface treatment, `finishes.toml` validated (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)  # no key takes NaN or inf

    finishes: dict[str, dict] = Field(default_factory=dict)
    coatings: dict[str, str] = Field(default_factory=lambda: {"default": "perfect-ar"})
    # No rules: every face keeps its mount finish. (A default of {"*": "absorber"} made adding
    # one rule flip every other face from absorber to its mount finish without a word.)
    assign: dict[str, str] = Field(default_factory=dict)

    @field_validator("coatings")
    @classmethod
    def _coatings(cls, v):
        return check_coatings(v)

    def tables(self) -> dict:
        """The three tables as a scene is built with them."""
        return {"finishes": dict(self.finishes), "coatings": dict(self.coatings), "assign": dict(self.assign)}


def load_finishes(design_root: str | Path) -> Finishes:
    """DESIGN/finishes.toml validated; the built-in treatment when the design has none."""
    path = Path(design_root) / FINISHES_NAME
    if not path.is_file():
        return Finishes()
    text = read_text(path, "finishes file", "the design's finishes.toml")
    data = parse_toml(text, str(path))
    try:
        spec = Finishes(**data)
        spec = spec.model_copy(update={"finishes": check_finishes(spec.finishes, spec.assign, path.parent)})
    except ValidationError as exc:
        raise input_error(exc, Finishes, file=str(path), text=text) from None
    except InputError as exc:
        raise located(exc, str(path), text) from None
    spec._file, spec._text = str(path), text
    return spec


def check_mount_finishes(finishes: Finishes, mount) -> None:
    """InputError (naming mount.toml's field and line) for a finish the mount file gives that
    the design's finishes.toml does not define.

    Defined: the built-in library, finishes.toml's `[finishes]`, and names its `finish:`
    rules re-assign (a mount finish may be a label finishes.toml maps). A misspelt finish would
    otherwise absorb silently wherever no rule covers it. Needs no geometry, so it runs
    before the regenerate.
    """
    library = finish_library(finishes.finishes)
    labels = {key.partition(":")[2] for key in finishes.assign if key.startswith("finish:")}
    defined = sorted(set(library) | labels)
    for field, name in mount.finish_fields().items():
        if name not in defined:
            guess = did_you_mean(name, defined)
            raise InputError(f"finish '{name}' is not defined" + (f" (did you mean '{guess}'?)" if guess else ""),
                             file=mount.source_file, field=field, line=line_of_key(mount.source_text, field),
                             valid="a defined finish: " + ", ".join(defined)
                                   + "; or define it in the design's finishes.toml [finishes]")


def old_layout_error(scene_file: str, tables: list[str]) -> InputError:
    """The error for a scene file that still holds the design's surface treatment, saying how to move it."""
    held = ", ".join(f"[{t}]" for t in tables)
    scene = Path(scene_file).absolute()
    design = scene.parent.parent if scene.parent.name == "scenes" else Path("DESIGN")
    return InputError(
        f"the scene file holds {held}, which belong to the design now: finishes, coatings and which faces "
        f"get which are part of the design, shared by all its scenes, so that `compare` judges a paint "
        f"change as a design revision, and a scene is only the test condition (source, detector, effects, "
        f"objects, run). Move these tables, unchanged, from the scene file into {design / FINISHES_NAME} "
        f"(create it; a measured finish's file path is then relative to the design folder) and delete them "
        f"from every scene file; if the design's scenes gave different treatments, each treatment is its own "
        f"design (a copy of the folder with its own finishes.toml), and a scene that counted only some faces' "
        f"scatter says so with [effects] scatter = [\"role:...\", \"finish:...\"]",
        file=scene_file, field=tables[0], valid="a scene file with description, [source], [detector], [effects], "
        "[[objects]] and [run] only (docs/mount-toml.md, 'The design's finishes: finishes.toml')")


__all__ = ["BUILTIN_FINISHES", "FINISHES_NAME", "Finishes", "finish_library", "check_rules", "check_coatings",
           "check_finishes", "check_mount_finishes", "deciding_rule", "finish_of", "load_finishes", "old_layout_error", "surface_rule"]
