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
        encoding = "utf-16"
    elif raw[:200].count(b"\x00") > 20:  # UTF-16 without a BOM
        encoding = "utf-16-le" if raw[1:2] == b"\x00" else "utf-16-be"
    else:
        try:
            return raw.decode("utf-8-sig")
        except UnicodeDecodeError:
            return raw.decode("latin-1")
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as exc:  # a truncated or damaged UTF-16 file: an odd byte count, a lone surrogate
        line = raw[:exc.start].decode(encoding, errors="replace").count("\n") + 1
        raise InputError(f"the file is damaged: it reads as UTF-16 (as Zemax writes it), but byte {exc.start} is "
                         f"not ({exc.reason})", file=str(path), line=line,
                         valid="a whole .zmx file (restore it from a copy or your version control)") from None


__all__ = ["ImportNote", "read_text"]
