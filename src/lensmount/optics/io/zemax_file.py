"""What every reader of Zemax's files shares: the text of a file as Zemax writes it (UTF-16 or
UTF-8, Latin-1 at worst) and the note an import leaves for each thing it did."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lensmount.errors import InputError


@dataclass(frozen=True)
class ImportNote:
    """One row of what the import did: `kind` is imported, substituted or ignored."""

    kind: str
    where: str
    what: str
    surface: int | None = None  # lensmount's 0-based surface, for a value the import leaves to real rays
    file_value_mm: float | None = None  # the value the file held there (what the recomputed one is set beside)


def read_text(path) -> str:
    """Decode a .zmx file: UTF-16 (BOM) or UTF-8, falling back to Latin-1."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", file=str(path), valid="a path to an existing .zmx or lens.toml") from None
    except OSError as exc:
        raise InputError(f"cannot read the file ({exc})", file=str(path), valid="a readable .zmx file") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        return raw.decode("utf-16")
    if raw[:200].count(b"\x00") > 20:  # UTF-16 without a BOM
        return raw.decode("utf-16-le" if raw[1:2] == b"\x00" else "utf-16-be")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


__all__ = ["ImportNote", "read_text"]
