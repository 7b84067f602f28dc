"""`lensmount history DESIGN [--scene S] [--plot FILE]`: stored runs across revisions, in commit order."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.table import Table

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.errors import InputError
from lensmount.loop.history import HistoryOptions, history as load_history, label, write_history_plot


@COMMANDS.register("history", CommandLine)
def history(
    design: Path = typer.Argument(..., help="Design folder."),
    scene: Optional[str] = typer.Option(None, "--scene", help="Only runs of this scene (name or file)."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Also write a PNG: stray fraction per revision "
                                                             "with error bars."),
    store: Optional[Path] = typer.Option(None, "--store", help="Results store (default DESIGN/.lensmount/"
                                                               "runs.sqlite or $LENSMOUNT_STORE)."),
) -> None:
    """Stray fraction across the design's revisions: commit ('*' = uncommitted changes), scene, value ± error.

    'test' is the run's test condition (a hash of the scene's source, detector, effects and objects;
    not its run length): runs with different ones are different tests, which `compare` refuses."""
    try:
        if not Path(design).is_dir():
            raise InputError("design folder not found", file=str(design), valid="a design folder")
        runs = load_history(HistoryOptions(design, scene, store))
    except InputError as error:
        fail(error)
    if not runs:
        typer.echo(f"{design}: no stored runs" + (f" of scene {scene}" if scene else "") +
                   "; `lensmount simulate` records each run")
        return
    table = Table(title=f"{Path(design).resolve().name}: {len(runs)} runs, oldest revision first "
                        "(* = uncommitted changes)", title_justify="left")
    for col in ("run", "commit", "committed", "scene", "test", "method", "passes", "stray fraction", "bias bound",
                "input"):
        table.add_column(col, justify="right" if col in ("run", "passes", "stray fraction", "bias bound") else "left")
    for r in runs:
        when = time.strftime("%Y-%m-%d %H:%M", time.gmtime(r.git_commit_time)) if r.git_commit_time else "—"
        value = "—" if r.stray_fraction is None else f"{r.stray_fraction:.4g}" + (
            f" ± {r.stray_fraction_std_error:.2g}" if r.stray_fraction_std_error is not None else "")
        bias = f"{r.stray_fraction_bias_bound:.2g}" if r.stray_fraction_bias_bound is not None else "—"
        test = r.condition_sha256[:8] if r.condition_sha256 else "—"
        table.add_row(str(r.id), label(r), when, r.scene_name, test, r.method, str(r.passes), value, bias,
                      r.input_hash[:10])
    Console(width=160).print(table)
    tests = {(r.scene_name, r.condition_sha256) for r in runs if r.condition_sha256}
    if len(tests) > len({scene_name for scene_name, _ in tests}):
        typer.echo("note: a scene's test condition changed between these runs (column 'test'): those runs "
                   "measure different tests, not revisions of the design")
    if plot is not None:
        write_history_plot(plot, runs, f"{Path(design).resolve().name}" + (f" · {scene}" if scene else ""))
        typer.echo(f"wrote {plot}")
