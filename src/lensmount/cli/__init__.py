"""The `lensmount` command: init · inspect · regenerate · check · simulate · compare · history.

Each command group lives in its own module and registers itself on `app`; each
parses its options, calls lensmount.loop (or the layer it fronts) and prints. This
module only turns user errors into one paragraph on stderr with exit code 2.
"""

from __future__ import annotations

import importlib
import sys

import typer

from lensmount.errors import InputError

app = typer.Typer(
    name="lensmount",
    help="From a lens prescription to a mount in STEP and the stray light it scatters onto the detector.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.callback()
def _root() -> None:
    """regenerate → simulate → compare: the stray-light loop for lens mounts."""


def fail(error: InputError) -> None:
    """Print a user error as one paragraph and exit 2."""
    typer.echo(f"error: {error.paragraph()}", err=True)
    raise typer.Exit(code=2)


# Modules that define commands; each does `@app.command()` at import.
COMMAND_MODULES = ("inspect", "regenerate", "check", "simulate", "compare", "watch", "history", "pst", "converge", "sweep",
                   "ghosts", "fit_abg", "paths")

for _name in COMMAND_MODULES:
    importlib.import_module(f"lensmount.cli.{_name}")


def main() -> None:
    try:
        app()
    except InputError as error:
        typer.echo(f"error: {error.paragraph()}", err=True)
        sys.exit(2)
