"""User templates: a design's own Python file builds any part kind.

mount.toml names the file per part kind:

    [templates]
    hood = "templates/my_hood.py"

The file defines `make_part(name: str, params: dict)` and returns a build123d
`Part`/`Solid`/`Compound`, or a CadQuery `Workplane` or `Shape`. `params` are the
built-in template's parameters for that part (placement included: the result must
sit in the assembly frame, optical axis +z). Both libraries sit on OCP, so the
result is converted through its OCP shape. Faces that lie on the built-in
template's profile keep its roles; other faces are tagged `mount`, unless the
file also defines

    def face_role(name: str, params: dict, r: float, z: float) -> str | None

which names the role of the face through the point (r, z) (mm, a point in the
middle of each face): `vane-edge`, `diaphragm-edge`, `bevel`, `lens-edge` or
`mount`, or None to keep the profile's tag. That is how a template declares which
of its faces are knife edges and bores (a scene's `role:` rules then find them).
"""

from __future__ import annotations

import importlib.util
import hashlib
import math
from pathlib import Path

from lensmount.errors import InputError


def load_template(path: Path, kind: str):
    """The `make_part` function of a user template file."""
    if not path.is_file():
        raise InputError(f"user template for '{kind}' not found", file=str(path), field=f"templates.{kind}",
                         valid="a path, relative to the design folder, of a .py file defining make_part(name, params)")
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]
    spec = importlib.util.spec_from_file_location(f"lensmount_user_{kind}_{digest}", path)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # the user's code: report it as their input
        raise InputError(f"user template failed to load: {exc!r}", file=str(path), field=f"templates.{kind}",
                         valid="a Python file that imports and defines make_part(name, params)") from None
    fn = getattr(module, "make_part", None)
    if not callable(fn):
        raise InputError("user template defines no make_part(name, params)", file=str(path),
                         field=f"templates.{kind}", valid="a function make_part(name: str, params: dict)")
    role = getattr(module, "face_role", None)  # optional: the template's own face roles
    if role is not None and not callable(role):
        raise InputError("face_role in a user template must be a function", file=str(path),
                         field=f"templates.{kind}", valid="def face_role(name, params, r, z) -> role or None")
    return fn, role


USER_ROLES = ("vane-edge", "diaphragm-edge", "bevel", "lens-edge", "mount")


def declared_roles(solid, face_role, name: str, params: dict, fallback, path: Path, kind: str):
    """(role, surface) per face of `solid`: the template's `face_role` where it names one, else fallback."""
    out = []
    for f, default in zip(solid.faces(), fallback):
        p = f.position_at(0.5, 0.5)
        try:
            role = face_role(name, params, math.hypot(p.X, p.Y), p.Z)
        except Exception as exc:  # the user's code
            raise InputError(f"face_role failed: {exc!r}", file=str(path), field=f"templates.{kind}",
                             valid="def face_role(name, params, r, z) -> role or None") from None
        if role is None:
            out.append(default)
        elif role in USER_ROLES:
            out.append((role, -1))
        else:
            raise InputError(f"face_role returned {role!r} for {name}", file=str(path), field=f"templates.{kind}",
                             valid=", ".join(USER_ROLES) + ", or None")
    return out


def to_solid(obj, path: Path, kind: str):
    """Convert a build123d or CadQuery result to one build123d Solid (via OCP)."""
    # lazy: build123d/OCP take seconds to load; planning a layout does without them
    from build123d import Compound, Shape

    wrapped = None
    if hasattr(obj, "vals") and hasattr(obj, "val"):  # cadquery Workplane
        vals = [v for v in obj.vals() if hasattr(v, "wrapped")]
        if len(vals) == 1:
            wrapped = vals[0].wrapped
        elif vals:  # build123d makes the compound, so the runtime needs no CadQuery of its own
            wrapped = Compound([Shape.cast(v.wrapped) for v in vals]).wrapped
    elif hasattr(obj, "wrapped"):  # build123d Shape or cadquery Shape
        wrapped = obj.wrapped
    if wrapped is None:
        raise InputError(f"user template returned {type(obj).__name__}", file=str(path), field=f"templates.{kind}",
                         valid="a build123d Part/Solid or a CadQuery Workplane/Shape")
    shape = Shape.cast(wrapped)
    solids = shape.solids()
    if len(solids) == 1:
        return solids[0]
    if not solids:
        raise InputError("user template returned no solid", file=str(path), field=f"templates.{kind}",
                         valid="a closed solid")
    return Compound(solids)


__all__ = ["load_template", "to_solid", "declared_roles", "USER_ROLES"]
