"""`lensmount watch DESIGN --scene S`: judge every saved edit against a baseline; parses, calls, prints."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.cli.compare import _fraction
from lensmount.cli.simulate import TerminalObserver, duration
from lensmount.analysis.compare import UNDECIDED
from lensmount.errors import InputError
from lensmount.loop.compare import verdict_sentence
from lensmount.loop.watch import WatchOptions, watch as watch_design


@COMMANDS.register("watch", CommandLine)
def watch(
    design: Path = typer.Argument(..., help="Design folder to watch."),
    scene: str = typer.Option(..., "--scene", help="Scene name or file: the test condition of every revision."),
    against: Optional[str] = typer.Option(None, "--against",
                                          help="Baseline from the store: last | best | a git revision "
                                               "(default: the design as it is when watching starts)."),
    tolerance: str = typer.Option("5%", "--tolerance", help="Allowed increase, relative to the baseline."),
    confidence: str = typer.Option("0.99", "--confidence", help="Confidence of the interval on the change."),
    time_s: Optional[float] = typer.Option(None, "--time", help="Seconds of tracing of a revision's first look "
                                                               "(default: simulate --quick's rules)."),
    passes: Optional[int] = typer.Option(None, "--passes", help="Passes of a revision's first look "
                                                                "(default: simulate --quick's rules)."),
    photons_per_pass: Optional[int] = typer.Option(None, "--photons-per-pass", help="Photons per pass."),
    workers: int = typer.Option(0, "--workers", help="Worker processes (0 = one per core)."),
    store: Optional[Path] = typer.Option(None, "--store", help="Results store (default DESIGN/.lensmount/"
                                                               "runs.sqlite or $LENSMOUNT_STORE)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder of watch.html and the comparisons "
                                                           "(default DESIGN/.lensmount/watch)."),
    glass_catalog: GlassCatalogs = [],
    budget: float = typer.Option(600.0, "--budget", help="Seconds of further tracing per revision after its first "
                                                         "look, while the verdict is undecided."),
) -> None:
    """Keep the loop warm: on every save of a design file, regenerate what changed, simulate the
    scene and print the verdict against the baseline (also in OUT/watch.html, which reloads
    itself). Each revision is first looked at after a quick run (simulate --quick), then resumed
    by the passes that would decide it (compare --until-decided) within --budget. A revision that
    does not build is explained and watching goes on. Ctrl-C stops."""
    observer = TerminalObserver(live=sys.stderr.isatty())
    try:
        options = WatchOptions(design, scene, against, _fraction(tolerance, "--tolerance"),
                               _fraction(confidence, "--confidence"), time_s, passes, photons_per_pass, workers,
                               store, out, budget_s=budget)
        for revision in watch_design(options, observer):
            observer.close()  # the revision's progress bars end; its verdict follows
            if revision.number == 0:
                typer.echo(f"baseline ready ({duration(revision.seconds)}); watching {design} — save a file "
                           "to judge it, Ctrl-C to stop", err=True)
            elif revision.error is not None:
                typer.echo(f"revision {revision.number} ({', '.join(revision.changed)}) does not build: "
                           f"{revision.error}", err=True)
            else:
                r = revision.result
                typer.echo(f"revision {revision.number} ({', '.join(revision.changed)}, "
                           f"{duration(revision.seconds)}): {verdict_sentence(r.verdict)}")
                if r.verdict.verdict == UNDECIDED:  # why, and what would decide it
                    typer.echo(f"  {r.stopped or r.verdict.note}")
    except InputError as error:
        observer.close()
        fail(error)
    except KeyboardInterrupt:
        observer.close()
        typer.echo("watch stopped", err=True)
        raise typer.Exit(code=130)
