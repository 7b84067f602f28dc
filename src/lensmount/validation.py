"""What the three input files share: TOML syntax errors and unknown keys, as InputErrors."""

from __future__ import annotations

import re
import tomllib
from typing import get_args

from pydantic import BaseModel

from lensmount.errors import InputError


def parse_toml(text: str, file: str, valid: str = "TOML syntax (https://toml.io)") -> dict:
    """tomllib.loads, with a syntax error reported as file + line (3.11 only says it in the text)."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        line = getattr(exc, "lineno", None)
        if line is None:
            m = re.search(r"at line (\d+)", str(exc))
            line = int(m.group(1)) if m else None
        message = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(exc))
        raise InputError(f"not valid TOML: {message}", file=file, line=line, valid=valid) from None


def keys_at(model: type[BaseModel], loc: tuple) -> list[str]:
    """The keys a file may use in the table that `loc` (a pydantic error location) points into.

    Walks the model's fields along loc; list indices and dict keys (parts of loc that
    are not field names) are stepped over.
    """
    current: type[BaseModel] | None = model
    for part in loc[:-1]:
        if current is None:
            return []
        field = _field(current, part)
        if field is not None:
            current = _model_in(field.annotation)
    if current is None:
        return []
    return [f.alias or name for name, f in current.model_fields.items()]


def _field(model: type[BaseModel], key):
    if not isinstance(key, str):
        return None
    for name, f in model.model_fields.items():
        if key in (name, f.alias):
            return f
    return None


def _model_in(annotation) -> type[BaseModel] | None:
    """The first pydantic model inside a type (Optional[M], list[M], dict[str, M], ...)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None
