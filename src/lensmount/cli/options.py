"""Options that several commands share, defined once.

`--glass-catalog`: on every command that reads a lens (inspect, init, regenerate, check, simulate,
compare, watch, pst, ghosts, sweep, converge, paths), a Zemax .agf glass catalogue that every lens the
command loads searches after its own (a lens.toml's `glass_catalogs`), before the built-in catalogues.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def _for_this_command(ctx: typer.Context, value: list[Path]) -> list[Path]:
    """The catalogues hold for the command being run and end with it (a test's CliRunner runs many)."""
    from lensmount.design.lens import use_command_glass_catalogs  # lazy: `lensmount --help` loads no optics

    use_command_glass_catalogs(value)
    ctx.call_on_close(lambda: use_command_glass_catalogs(()))
    return value


GlassCatalogs = Annotated[list[Path], typer.Option(
    "--glass-catalog", callback=_for_this_command, metavar="FILE.agf",
    help="A Zemax .agf glass catalogue searched for the lens's glass names before the built-in catalogues "
         "(repeatable; after a lens.toml's own glass_catalogs). Applies to every lens the command loads.")]

__all__ = ["GlassCatalogs"]
