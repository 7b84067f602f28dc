"""Finishes: named surface treatments mapped to BSDF models, and the rules that assign them to faces.

Built-in library (a scene's `[finishes]` table adds to or overrides it):

| finish           | model                                   |
|------------------|-----------------------------------------|
| `absorber`       | absorber (ends every path)              |
| `black-anodised` | lambertian, reflectance 0.05            |
| `ground-glass`   | lambertian, reflectance 0.10            |
| `mirror`         | mirror, reflectance 1                   |

Assignment (`[assign]`), most specific wins:
`part:NAME` > `role:ROLE` > `kind:KIND` > `finish:NAME` (the finish the mount file gave the face)
> `"*"`. A face matched by no rule keeps the finish its mount file gave it, which must be
defined (an undefined one is an error, never a silent absorber); a rule that matches no face is
an error too (scene.build). Optical faces are never assigned a finish (the tracer refracts
there), except a mirror's coated face by `"surface:N"` (N its 1-based surface number): that
finish is the scatter on top of the specular reflection (micro-roughness, dust). Only the rule
naming the surface reaches it: `"*"` or `part:` rules meant for the blank and the cells would
otherwise turn every mirror of an existing scene into a 5 % Lambertian one.
"""

from __future__ import annotations

from lensmount.mesh import FaceTag
from lensmount.errors import InputError

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


def finish_of(tag: FaceTag, assign: dict[str, str], library: dict[str, dict]) -> str | None:
    """The finish name for a face tag; for an optical face the `surface:N` rule's finish, else None
    (whether surface N is a mirror is `scene.build.check_rules_match`'s to say)."""
    if tag.role == "optical":
        return assign.get(surface_rule(tag.surface)) if tag.surface >= 0 else None
    for prefix in _PRIORITY:
        key = f"{prefix}:{getattr(tag, prefix)}"
        if key in assign:
            return assign[key]
    if "*" in assign:
        return assign["*"]
    if tag.finish not in library:  # never absorb silently: a misspelt mount finish would read as black
        raise InputError(f"part '{tag.part}' has the finish '{tag.finish}' from its mount file, which is not defined, "
                         "and no [assign] rule covers it", field="assign",
                         valid="a defined finish in the mount file (" + ", ".join(sorted(library))
                               + "), a [finishes] entry of that name, or an [assign] rule for the part")
    return tag.finish


__all__ = ["BUILTIN_FINISHES", "finish_library", "check_rules", "finish_of", "surface_rule"]
