"""What the three input files share: reading their text, TOML syntax errors, unknown keys (with the keys allowed
there and a did-you-mean), pydantic errors as InputErrors, and the line a field sits on.

TOML parsers give no positions for keys, so `line_of_key` scans the file text for the key
within its table; every loader locates its errors through it.
"""

from __future__ import annotations

import difflib
import re
import tomllib
from typing import get_args

from pydantic import BaseModel, PrivateAttr, ValidationError

from lensmount.errors import InputError


class ReadFromFile(BaseModel):
    """A spec that remembers the file it was read from and its text, so that errors found later
    (a mount finish checked against a scene, a selector checked against the mesh) can name their line."""

    _file: str | None = PrivateAttr(None)
    _text: str | None = PrivateAttr(None)

    @property
    def source_file(self) -> str | None:
        """The file this spec was read from (None for a spec built in code)."""
        return self._file

    @property
    def source_text(self) -> str | None:
        return self._text


def read_text(path, what: str, valid: str) -> str:
    """An input file's UTF-8 text; InputError naming the file when it is missing, unreadable or
    damaged (bytes that are not UTF-8: a flipped bit, a truncated character), with the line."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{what} not found", file=str(path), valid=valid) from None
    except OSError as exc:
        raise InputError(f"cannot read the {what} ({exc.strerror or exc})", file=str(path), valid=valid) from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"the {what} is damaged or not text: byte {exc.start} is not UTF-8", file=str(path),
                         line=raw.count(b"\n", 0, exc.start) + 1,
                         valid=f"{valid}, as UTF-8 text (restore it from a copy or your version control)") from None


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


def input_error(exc: ValidationError, model: type[BaseModel], *, file: str | None = None,
                text: str | None = None, valid: str | None = None, prefix: tuple = ()) -> InputError:
    """The InputError for a pydantic ValidationError of `model` read from `file` (its `text`).

    An unknown key is reported before anything else: a misspelt key also leaves the right
    key missing, and "field required" for the right key would hide what the user typed.
    """
    errors = exc.errors()
    err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    loc = tuple(err["loc"])
    field = ".".join(str(x) for x in prefix + loc) or None  # prefix: where `model`'s table sits in the file
    allowed = keys_at(model, loc)
    if err["type"] == "extra_forbidden":
        key = str(loc[-1])
        guess = did_you_mean(key, allowed)
        message = f"unknown key '{key}'" + (f" (did you mean '{guess}'?)" if guess else "")
        valid = ", ".join(allowed) or valid
    elif err["type"] == "missing":
        message = f"missing key '{loc[-1]}'"
        valid = "a value for every required key; keys here: " + ", ".join(allowed)
    else:
        ctx = err.get("ctx") or {}
        bound = next((f"a number {op} {ctx[k]}" for k, op in _BOUNDS if k in ctx), None)
        message = f"{err['msg']} (got {err.get('input')!r})"
        valid = bound or _declared_bounds(model, loc) or valid
    return InputError(message, file=file, field=field, line=line_of_key(text, field), valid=valid)


_BOUNDS = (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))


def _declared_bounds(model: type[BaseModel], loc: tuple) -> str | None:
    """"a number >= 0 and <= 1" from the field's own constraints (a wrong type carries no bound of its own)."""
    current: type[BaseModel] | None = model
    for part in loc[:-1]:
        field = _field(current, part) if current is not None else None
        current = _model_in(field.annotation) if field is not None else current
    field = _field(current, loc[-1]) if current is not None and loc else None
    if field is None:
        return None
    said = [f"{op} {getattr(m, k)}" for m in field.metadata for k, op in _BOUNDS if getattr(m, k, None) is not None]
    return "a number " + " and ".join(said) if said else None


def located(exc: InputError, file: str | None, text: str | None) -> InputError:
    """The error with the file and, from the field, the line filled in where it has none."""
    return exc.located(file, line=line_of_key(text, exc.field))


def did_you_mean(word: str, choices) -> str | None:
    """The closest of `choices` to a misspelt `word`, if one is close."""
    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return close[0] if close else None


_KEY = r"""(?:"(?:[^"\\]|\\.)*"|'[^']*'|[A-Za-z0-9_-]+)"""
_DOTTED = rf"{_KEY}(?:\s*\.\s*{_KEY})*"
_HEADER = re.compile(rf"^\s*(\[\[?)\s*({_DOTTED})\s*\]")
_ASSIGN = re.compile(rf"^\s*({_DOTTED})\s*=")


def _parts(dotted: str) -> list[str]:
    return [p[1:-1] if p[0] in "\"'" else p for p in re.findall(_KEY, dotted)]


def line_of_key(text: str | None, field: str | None) -> int | None:
    """1-based line of a field path ('detector.width_mm', 'objects.0.finish', 'assign.role:x') in TOML text.

    Tables and arrays of tables (the n-th `[[objects]]` is 'objects.<n-1>') are followed; a
    key inside an inline table is found on the line of its table. Without an exact match the
    deepest enclosing table or key is given (a missing key: its table's header). Best effort:
    None when nothing matches.
    """
    if not text or not field:
        return None
    table: list[str] = []
    counts: dict[tuple, int] = {}
    best, best_len = None, -1
    for number, raw in enumerate(text.splitlines(), 1):
        head = _HEADER.match(raw)
        if head:
            table = _parts(head.group(2))
            if head.group(1) == "[[":
                k = counts.get(tuple(table), 0)
                counts[tuple(table)] = k + 1
                table = table + [str(k)]
            path = table
        else:
            assign = _ASSIGN.match(raw)
            if not assign:
                continue
            path = table + _parts(assign.group(1))
        rendered = ".".join(path)
        if rendered == field:
            return number
        if field.startswith(rendered + ".") and len(rendered) > best_len:
            best, best_len = number, len(rendered)
    return best


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
