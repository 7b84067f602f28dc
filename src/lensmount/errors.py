"""Errors a user can act on.

An `InputError` names the file, the field (or line) and what would be valid.
The CLI turns it into one paragraph on stderr and exit code 2, without a
traceback. Algorithms raise it only for problems in what the user gave them.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input: which file, which field or line, and what would be valid."""

    def __init__(self, message: str, *, file: str | None = None, field: str | None = None,
                 line: int | None = None, valid: str | None = None):
        self.file = file
        self.field = field
        self.line = line
        self.valid = valid
        self.detail = message
        super().__init__(self.paragraph())

    def paragraph(self) -> str:
        where = []
        if self.file:
            where.append(str(self.file))
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.field:
            where.append(f"field '{self.field}'")
        text = (", ".join(where) + ": " if where else "") + self.detail.rstrip(".") + "."
        if self.valid:
            text += f" Valid: {self.valid.rstrip('.')}."
        return text

    def located(self, file: str | None, line: int | None = None) -> "InputError":
        """The same error with the file (and line) filled in where it has none (for loaders that
        learn them late)."""
        if (self.file or not file) and (self.line is not None or line is None):
            return self
        return type(self)(self.detail, file=self.file or file, field=self.field,
                          line=self.line if self.line is not None else line, valid=self.valid)


class GeometryError(InputError):
    """Parts that interfere or violate a manufacturing limit (names both parts, overlap in mm)."""


class WorkersGone(Exception):
    """Every worker of a Dask cluster is gone and none came back within the wait limit. Not the
    user's input and not a crash: the run keeps what is complete and exits `EXIT_CODE` (75,
    EX_TEMPFAIL), which a batch script can retry on (docs/scale.md)."""

    EXIT_CODE = 75
