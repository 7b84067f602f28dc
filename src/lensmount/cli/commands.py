"""The `lensmount` verbs by name: each a module of this folder (or a user's plug-in) that registers its
command function, which `lensmount.cli` puts on the app.

    @COMMANDS.register("simulate", CommandLine)
    def simulate(design: Path = typer.Argument(...), ...):
        \"\"\"Simulate the stray light on the detector: ...\"\"\"   # its first line is the verb's summary in --help

A verb's options are its function's typer parameters, read by the command line itself; `CommandLine` says
so to the registry (no parameters beyond them). `fail` is how a verb reports a user error.
"""

from __future__ import annotations

import typer
from pydantic import BaseModel, ConfigDict

from lensmount.errors import InputError
from lensmount.registry import Registry


class CommandLine(BaseModel):
    """A verb takes its options from the command line (its function's typer parameters), nothing else."""

    model_config = ConfigDict(extra="forbid", frozen=True)


COMMANDS: Registry = Registry("command", where="lensmount --help", implementations="lensmount.cli")


def fail(error: InputError) -> None:
    """Print a user error as one paragraph and exit 2."""
    typer.echo(f"error: {error.paragraph()}", err=True)
    raise typer.Exit(code=2)


__all__ = ["COMMANDS", "CommandLine", "fail"]
