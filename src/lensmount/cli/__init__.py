"""The `lensmount` command: init · inspect · regenerate · check · simulate · compare · history.

Each command group lives in its own module and registers itself on `app`; each
parses its options, calls lensmount.loop (or the layer it fronts) and prints. This
module only turns user errors into one paragraph on stderr with exit code 2, and
SIGINT / SIGTERM at any moment of any command into one line and exit 130 / 143
(lensmount.run.signals): never click's bare "Aborted!".
"""

from __future__ import annotations

import importlib
import sys

import typer
from typer.core import TyperGroup

from lensmount.errors import InputError, WorkersGone
from lensmount.run.signals import exit_code, signal_name, stop_on_signals


class _Commands(TyperGroup):
    """Every command runs with SIGINT and SIGTERM raising (also when a script started it in the
    background with SIGINT ignored); a stop becomes its one line and 130 / 143."""

    def invoke(self, ctx):
        with stop_on_signals():
            try:
                return super().invoke(ctx)
            except KeyboardInterrupt as stop:
                typer.echo(str(stop) or f"{signal_name(stop)}: stopped, nothing half-written left; "
                                        "run the command again", err=True)
                raise typer.Exit(code=exit_code(stop)) from None
            except WorkersGone as gone:
                typer.echo(f"{gone} (exit {WorkersGone.EXIT_CODE}: retry later)", err=True)
                raise typer.Exit(code=WorkersGone.EXIT_CODE) from None


app = typer.Typer(
    cls=_Commands,
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
                   "ghosts", "fit_abg", "paths", "optimize")

for _name in COMMAND_MODULES:
    importlib.import_module(f"lensmount.cli.{_name}")


def main() -> None:
    try:
        app()
    except InputError as error:
        typer.echo(f"error: {error.paragraph()}", err=True)
        sys.exit(2)
