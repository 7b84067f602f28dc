"""`lensmount converge DESIGN --scene S`: parses, calls lensmount.loop.converge, prints."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.cli.simulate import duration
from lensmount.errors import InputError
from lensmount.loop.converge import ConvergeOptions, converge as run, read_reference, write_converge


@COMMANDS.register("converge", CommandLine)
def converge(
    design: Path = typer.Argument(..., help="Design folder (lens.toml or lens.zmx, mount.toml, scenes/)."),
    scene: Path = typer.Option(..., "--scene", help="Scene: a name from DESIGN/scenes/ or a scene file."),
    methods: str = typer.Option("bidirectional,forward", "--methods", help="Comma-separated: bidirectional,forward."),
    budget: float = typer.Option(600.0, "--budget", help="Seconds of tracing in total, shared by the methods."),
    levels: int = typer.Option(5, "--levels", help="Doubling time levels per method (the last = its budget)."),
    reference: Optional[str] = typer.Option(None, "--reference",
                                            help="Reference stray fraction: a number, or a long run's summary.json."),
    photons_per_pass: Optional[int] = typer.Option(None, "--photons-per-pass",
                                                   help="Photons per pass (default: the scene's run table)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed (default: the scene's)."),
    workers: int = typer.Option(0, "--workers", help="Worker processes (0 = one per core)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Output folder (default out/converge-<scene name>)."),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """What accuracy costs in time: each method runs for its share of the budget and is read
    at doubling times; writes converge.csv (time, photons, relative standard error, bias bound,
    error against the reference) and converge.png (error against time, log-log, with the
    1/√t slope drawn), and prints how long the next halving of the error takes per method."""
    out = Path(out) if out else Path("out") / f"converge-{Path(scene).stem}"
    try:
        ref = read_reference(reference)
        options = ConvergeOptions(Path(design), Path(scene), out, tuple(m.strip() for m in methods.split(",") if m.strip()),
                                  budget, levels, ref, photons_per_pass, seed, workers)
        curves = run(options, progress=lambda text: typer.echo(text, err=True))
        paths = write_converge(out, curves, ref)
    except InputError as error:
        fail(error)
    for c in curves:
        typer.echo(f"{c.method}:")
        for lv in c.levels:
            rel = "—" if lv.rel_std_error is None else f"{100 * lv.rel_std_error:.2f} %"
            rel += " (nothing reached the detector yet)" if lv.value == 0 else ""
            extra = "" if lv.rel_error_vs_reference is None else f" · vs reference {100 * lv.rel_error_vs_reference:.2f} %"
            extra += "" if lv.bias_bound is None else f" · bias bound {lv.bias_bound:.2g}"
            typer.echo(f"  {lv.time_s:8.1f} s  {lv.passes:5d} passes  {lv.photons:>13,} photons  "
                       f"{lv.value:.4g}  rel. std. error {rel}{extra}")
        few = [lv for lv in c.levels if lv.passes < 8]
        if few:
            typer.echo(f"  note: {len(few)} level(s) have fewer than 8 passes; their error bars are themselves "
                       "uncertain by ±25 % or more (a smaller --photons-per-pass gives more passes)")
        slope = "—" if c.slope is None else f"{c.slope:+.2f}"
        rate = "at the fitted slope" if c.halving_rate == "fitted" else "at the 1/√t rate (fitted slope implausible)"
        typer.echo(f"  slope {slope} (ideal −0.50); halving the error once more takes ~{duration(c.next_halving_s, 'unknown (no error bar yet)')}"
                   + (f" {rate}" if c.next_halving_s is not None else ""))
    typer.echo("wrote " + ", ".join(str(p) for p in paths.values()))
