"""`lensmount sweep DESIGN --scene S --param mount.hood.length_mm=80,100,120 ...`: parses, calls lensmount.loop.sweep, prints."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.table import Table

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.cli.simulate import observed
from lensmount.errors import InputError
from lensmount.loop.simulate import SimulateOptions
from lensmount.loop.sweep import Param, SweepOptions, sweep as run_sweep


@COMMANDS.register("sweep", CommandLine)
def sweep(
    design: Path = typer.Argument(..., help="Base design folder."),
    scene: Path = typer.Option(..., "--scene", help="Scene file every variant is simulated with."),
    param: List[str] = typer.Option(..., "--param",
                                    help="FILE.TABLE.KEY=V1,V2,... (FILE: mount, lens, finishes or scene), e.g. "
                                         "mount.hood.length_mm=80,100,120; repeat for a grid. A mount key whose values lay "
                                         "out the same parts is refused (vanes.count counts only under "
                                         "placement = \"even\")."),
    out: Path = typer.Option(Path("out/sweep"), "--out", help="Folder for the variants, sweep.csv and sweep.png."),
    method: str = typer.Option("bidirectional", "--method", help="bidirectional | forward | a plug-in integrator."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed for every variant (default: the scene's)."),
    passes: Optional[int] = typer.Option(None, "--passes", help="Passes per variant."),
    photons_per_pass: Optional[int] = typer.Option(None, "--photons-per-pass", help="Photons per pass."),
    time_s: Optional[float] = typer.Option(None, "--time", help="Seconds per variant."),
    target_rel_error: Optional[float] = typer.Option(None, "--target-rel-error", help="Relative error per variant."),
    workers: int = typer.Option(0, "--workers", help="Worker processes (0 = one per core)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", envvar="LENSMOUNT_SCHEDULER",
                                            help="Run the passes on this Dask scheduler."),
    cluster: Optional[str] = typer.Option(None, "--cluster", help="Start a Dask LocalCluster: local:N processes."),
    confidence: float = typer.Option(0.95, "--confidence", help="Variants closer than this confidence allows "
                                                                "are ties."),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """Regenerate and simulate every combination of the parameters; rank the variants, ties within the noise.

    Writes OUT/variants/NN/ (design copy, geometry, results), OUT/sweep.csv and OUT/sweep.png.
    """
    try:
        params = tuple(Param.parse(p) for p in param)
    except InputError as error:
        fail(error)
    base = SimulateOptions(design, scene, method=method, seed=seed, photons_per_pass=photons_per_pass,
                           passes=passes, time_s=time_s, target_rel_error=target_rel_error, workers=workers,
                           argv=list(sys.argv), scheduler=scheduler, cluster=cluster, record=False)
    result = observed(run_sweep, SweepOptions(design, scene, params, out, base, confidence))
    _print(result, params)


def _print(result, params) -> None:
    table = Table(title="sweep: lowest stray fraction first; equal ranks are ties within the noise",
                  title_justify="left")
    for column in ["rank", "variant", *(p.name for p in params), "stray fraction", "tied with"]:
        table.add_column(column, justify="right")
    for v in sorted(result.variants, key=lambda v: (v.rank, v.index)):
        value = "—" if v.stray_fraction is None else f"{v.stray_fraction:.4g}" + (
            f" ± {v.std_error:.2g}" if v.std_error is not None else "")
        table.add_row(str(v.rank), str(v.index), *(str(v.values[p.name]) for p in params), value,
                      " ".join(map(str, v.tied_with)) or "—")
    console = Console()
    console.print(table)
    console.print(f"wrote {result.table}" + (f", {result.plot}" if result.plot else ""))
