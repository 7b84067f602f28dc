"""`lensmount compare A B` and `lensmount compare DESIGN --scene S --against last|best|REV`: parse, call, print.

Exit codes: 0 no significant regression (also "undecided": noise is never a
regression), 1 regression beyond the tolerance at the confidence asked, 2 bad input
or runs that do not measure the same thing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.table import Table

from lensmount.analysis.compare import REGRESSION, UNDECIDED, parse_fraction
from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.cli.simulate import QUICK_HELP, duration, observed
from lensmount.errors import InputError
from lensmount.loop.pst_report import compare_curves
from lensmount.loop.compare import (CompareOptions, RunSource, compare as run_compare, part_label, part_rows, plan,
                                   verdict_row)


def _fraction(text: str, field: str) -> float:
    try:
        return parse_fraction(text, field)
    except ValueError as exc:
        raise InputError(str(exc), field=field, valid="a fraction such as 5% or 0.05") from None


def announce(source: RunSource) -> str:
    """Which run a side takes, or what it must simulate and about how long, said before it starts."""
    if source.record is not None:
        r = source.record
        return (f"{source.role}: stored run {r.id} ({source.why}; {r.passes} passes, {r.photons:,} photons, "
                f"{r.created_utc}, {r.git_commit[:10] if r.git_commit else 'no commit'}"
                f"{'*' if r.git_dirty else ''}) from {source.folder}")
    if source.simulate is None:
        return f"{source.role}: {source.folder}"
    length = f"for {duration(source.estimate_s)}" if source.simulate.time_s is not None else (
        f"about {source.passes} passes × {source.photons_per_pass:,} photons, {duration(source.estimate_s)}"
        if source.estimate_s is not None else f"at most {source.passes} passes × {source.photons_per_pass:,} "
        "photons, an unknown time (no stored run of this scene to go by)")
    return (f"{source.role}: no stored run of this design and test condition: simulating {length} "
            f"into {source.folder} (--quick, --passes, --photons-per-pass or --time shorten it)")


def compare_pst(a: Path, b: Path, tolerance: str, confidence: str) -> None:
    """Two PST curves (folders `lensmount pst` wrote), angle by angle; exit 1 naming the angles that regressed."""
    try:
        tol, conf = _fraction(tolerance, "--tolerance"), _fraction(confidence, "--confidence")
        rows, notes = compare_curves(a, b, tol, conf)
    except InputError as error:
        fail(error)
    for note in notes:
        typer.echo(f"note: {note}", err=True)
    for angle, v in rows:
        typer.echo(f"{angle:6g}°  PST {v.old:.4g} → {v.new:.4g}  {v.verdict}" + (f" — {v.note}" if v.note else ""))
    worse = [f"{angle:g}°" for angle, v in rows if v.verdict == REGRESSION]
    typer.echo(f"regression at {', '.join(worse)}" if worse else "no angle regressed beyond the tolerance")
    raise typer.Exit(code=1 if worse else 0)


@COMMANDS.register("compare", CommandLine)
def compare(
    a: Path = typer.Argument(..., help="Old run: a results folder, or a design folder (with --scene)."),
    b: Optional[Path] = typer.Argument(None, help="New run: a results folder or a design folder; "
                                                  "omit with --against."),
    scene: Optional[str] = typer.Option(None, "--scene", help="Scene name or file, for design folders."),
    against: Optional[str] = typer.Option(None, "--against",
                                          help="Compare the design's current state with a stored run: "
                                               "last | best | a git revision."),
    metric: str = typer.Option("stray_fraction", "--metric", help="stray_fraction | stray_flux_mm2"),
    tolerance: str = typer.Option("5%", "--tolerance", help="Allowed increase, relative to the old value."),
    confidence: str = typer.Option("0.99", "--confidence", help="Confidence of the interval on the change."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for difference.exr/png and compare.json "
                                                           "(default NEW/compare)."),
    store: Optional[Path] = typer.Option(None, "--store", help="Results store (default DESIGN/.lensmount/"
                                                               "runs.sqlite or $LENSMOUNT_STORE)."),
    method: str = typer.Option("bidirectional", "--method", help="Method for runs that must be simulated."),
    workers: int = typer.Option(0, "--workers", help="Worker processes for runs that must be simulated."),
    passes: Optional[int] = typer.Option(None, "--passes", help="Passes for runs that must be simulated "
                                                                "(default: the scene's run.passes)."),
    photons_per_pass: Optional[int] = typer.Option(None, "--photons-per-pass",
                                                   help="Photons per pass for runs that must be simulated."),
    time_s: Optional[float] = typer.Option(None, "--time", help="Seconds per run that must be simulated."),
    until_decided: bool = typer.Option(False, "--until-decided",
                                       help="While undecided, resume the runs by the passes that would decide "
                                            "it and look again; each look's interval is wider so that all looks "
                                            "together keep --confidence."),
    budget: float = typer.Option(3600.0, "--budget", help="Seconds of further tracing --until-decided may spend."),
    glass_catalog: GlassCatalogs = [],
    quick: bool = typer.Option(False, "--quick", help="Runs that must be simulated: " + QUICK_HELP),
) -> None:
    """Is the new run worse than the old one? Old, new, change with its interval, per part, and the verdict.

    Exit 0: no significant regression (or undecided: then it says how many more passes of
    which run would decide; --until-decided runs them). Exit 1: a regression beyond the tolerance
    at that confidence. Exit 2: bad input or runs of different test conditions (the scene's
    source, detector, effects, objects). The design may differ (lens, mount, finishes.toml, user
    files): what changed is listed beside the verdict, and a part in one run only reads added or
    removed. Before anything runs it says which stored run each side takes, or what it must
    simulate and about how long (stored runs match by design and test condition, whatever their length).
    """
    if b is not None and (a / "pst.csv").is_file() and (b / "pst.csv").is_file():
        compare_pst(a, b, tolerance, confidence)  # two PST curves: angle by angle
    try:
        options = CompareOptions(a, b, scene, against, metric, _fraction(tolerance, "--tolerance"),
                                 _fraction(confidence, "--confidence"), out, store, method, workers, passes,
                                 photons_per_pass, time_s, until_decided, budget, quick)
        sources = plan(options)
    except InputError as error:
        fail(error)
    for source in sources:
        typer.echo(announce(source), err=True)
    result = observed(lambda observer: run_compare(options, observer, sources))
    v = result.verdict
    console = Console()
    for note in result.notes:
        console.print(f"note: {note}", style="yellow")
    typer.echo("design changes:" + ("" if result.design_changes else " none"))
    for change in result.design_changes:
        typer.echo(f"  {change}")
    table = Table(title=f"{result.metric}: old {result.old.folder} → new {result.new.folder}; tolerance "
                        f"{100 * options.tolerance:g} %, interval at {100 * options.confidence:g} %",
                  title_justify="left")
    for col in ("", "old", "new", "change", "interval of the change", "verdict"):
        table.add_column(col, justify="right" if col else "left")
    table.add_row("total", *verdict_row(v), style="bold")
    for name, pv in sorted(result.per_part.items(), key=lambda kv: -max(kv[1].old, kv[1].new)):
        if pv.old or pv.new:
            table.add_row(part_label(result, name), *verdict_row(pv))
    for row in part_rows(result):
        table.add_row(*row)
    console.print(table)
    typer.echo(f"verdict: {v.verdict}" + (f" — {v.note}" if v.note else ""))
    if v.verdict == UNDECIDED and v.more_photons is not None:
        typer.echo(f"to decide: about {v.more_photons:,} more photons (~{duration(v.more_time_s)} at the runs' "
                   f"speed); --until-decided resumes them")
    typer.echo("wrote " + ", ".join(str(p) for p in result.paths.values()))
    raise typer.Exit(code=result.exit_code)
