"""Errors a user can act on.

An `InputError` names the file, the field (or line) and what would be valid.
The CLI turns it into one paragraph on stderr and exit code 2, without a
traceback. Algorithms raise it only for problems in what the user gave them.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input: which file, which field or line, and what would be valid."""

    def __init__(self, message: str, *, file: str | None = None, field: str | None = None,
                 line: int | None = None, valid: str | None = None, names_file: str | None = None):
        self.file = file
        self.names_file = names_file  # the file the field names (a STEP file, a template), when the fault is in it
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
            where.append(f"field '{self.field}'" + (f" ({self.names_file})" if self.names_file else ""))
        text = (", ".join(where) + ": " if where else "") + self.detail.rstrip(".") + "."
        if self.valid:
            text += f" Valid: {self.valid.rstrip('.')}."
        return text

    def located(self, file: str | None, line: int | None = None) -> "InputError":
        """The same error with the file (and line) filled in where it has none (for loaders that
        learn them late). A line is the line of `file`: an error about another file (the STEP file
        or template a field of `file` names) is placed at that field's line of `file` and names its
        own file beside the field."""
        if self.file and file and line is not None and self.line is None and str(self.file) != str(file):
            return type(self)(self.detail, file=file, field=self.field, line=line, valid=self.valid,
                              names_file=self.file)
        if (self.file or not file) and (self.line is not None or line is None):
            return self
        return type(self)(self.detail, file=self.file or file, field=self.field,
                          line=self.line if self.line is not None else line, valid=self.valid,
                          names_file=self.names_file)


class GeometryError(InputError):
    """Parts that interfere or violate a manufacturing limit (names both parts, overlap in mm)."""


class WorkersGone(Exception):
    """Every worker of a Dask cluster is gone and none came back within the wait limit. Not the
    user's input and not a crash: the run keeps what is complete and exits `EXIT_CODE` (75,
    EX_TEMPFAIL), which a batch script can retry on (docs/scale.md)."""

    EXIT_CODE = 75
