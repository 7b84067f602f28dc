"""A CLI verb added the way docs/architecture.md says ("Where to add a command"): this file, which registers
itself in `COMMANDS`, and its line in the plug-in package's entry points; nothing of lensmount touched.

    lensmount tis abg A=1e-3 B=1e-4 g=2      # prints the finish's total integrated scatter
"""

from __future__ import annotations

import typer

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.errors import InputError


@COMMANDS.register("tis", CommandLine)
def tis(model: str = typer.Argument(..., help="BSDF model, as a finish names it"),
        params: list[str] = typer.Argument(None, help="KEY=VALUE parameters of the model")) -> None:
    """Total integrated scatter of a finish at normal incidence."""
    from lensmount.physics.bsdf import make_bsdf  # lazy: keeps lensmount --help from loading the BSDF models

    values = {}
    for item in params or []:
        key, _, value = item.partition("=")
        try:
            values[key] = float(value)
        except ValueError:
            fail(InputError(f"'{item}' is not KEY=NUMBER", field=key or item, valid="KEY=NUMBER, e.g. reflectance=0.1"))
    try:
        typer.echo(f"{make_bsdf(model, **values).tis:.6g}")
    except InputError as error:
        fail(error)
