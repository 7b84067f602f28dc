"""`lensmount optimize DESIGN`: parses, calls lensmount.loop.optimize, prints."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.table import Table

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.simulate import TerminalObserver, observed
from lensmount.loop.optimize import OptimizeObserver, OptimizeOptions, optimize as run_optimize
from lensmount.loop.optimize_report import OptimizeResult


class _Observer(TerminalObserver, OptimizeObserver):
    """simulate's stages and passes, and a bar over the candidates."""

    def candidate(self, done: int, total: int) -> None:
        width = 30
        filled = round(width * done / total)
        self._say(f"[{'#' * filled}{'-' * (width - filled)}] {done}/{total} candidates")


@COMMANDS.register("optimize", CommandLine)
def optimize(
    design: Path = typer.Argument(..., help="The start design folder."),
    spec: Optional[Path] = typer.Option(None, "--spec", help="The [optimize] table (default DESIGN/optimize.toml)."),
    out: Path = typer.Option(Path("out/optimize"), "--out", help="Candidates, the best revision and the report."),
    trials: Optional[int] = typer.Option(None, "--trials", help="Candidates to evaluate (default: the table's)."),
    budget: Optional[int] = typer.Option(None, "--budget", help="Evaluate at most this many candidates now; the "
                                                                "same command later resumes the study."),
    store: Optional[Path] = typer.Option(None, "--store", help="The run store (the study sits beside it)."),
    method: str = typer.Option("bidirectional", "--method", help="bidirectional | forward"),
    workers: int = typer.Option(0, "--workers", help="Worker processes per simulation (0 = one per core)."),
) -> None:
    """Search the mount's keys for the lowest stray fraction of a scene; prove the best on fresh seeds.

    DESIGN/optimize.toml names the variables (numeric mount.toml keys with bounds, whole numbers with
    integer = true, finishes from finishes.toml), the objective (a scene's stray fraction), the
    constraints (overall length, outer diameter; every candidate must also regenerate and pass the
    mount's checks) and the fidelity. See lensmount.loop.optimize_spec for the table.

    Each candidate is a design folder under OUT/candidates/NNN, regenerated and simulated with the
    same seed as every other (common random numbers); contenders earn more passes and a new best is
    re-evaluated at twice them. The search is Optuna's TPE, its study in SQLite beside the run store:
    an interrupted optimize resumes with the same command and ends where an uninterrupted one would.
    At the end the best is written as OUT/best/design (mount.toml, its STEP in OUT/best/build, a row
    in the store) and judged against the start by `compare` on a seed the search never used.
    The report: OUT/optimize.json, OUT/history.csv, OUT/history.png.
    """
    result = observed(run_optimize, OptimizeOptions(design, spec, out, trials, budget, store, method, workers),
                      kind=_Observer)
    _print(result)


def _print(r: OptimizeResult) -> None:
    console = Console()
    keys = list(r.spec.variables)
    table = Table(title="optimize: candidates on the search seed (common random numbers)", title_justify="left")
    for column in ["#", *keys, "stray fraction", "passes", "note"]:
        table.add_column(column, justify="right", overflow="fold")
    for c in [r.start, *r.candidates]:
        value = "—" if c.value is None else f"{c.value:.4g}±{c.std_error:.1g}"
        note = "best" if c is r.best else ("" if c.feasible else "infeasible")
        table.add_row("start" if c.index < 0 else str(c.index + 1), *(str(c.values[k]) for k in keys), value,
                      str(c.passes), note)
    console.print(table)
    for c in r.candidates:
        if not c.feasible:
            console.print(f"candidate {c.index + 1} is infeasible: {c.why}")
    console.print(f"common random numbers: var(difference) shared / independent seeds = "
                  f"{r.crn.shared_variance:.3g} / {r.crn.independent_variance:.3g} = {r.crn.ratio:.3g} "
                  f"({r.crn.passes} passes, start against {r.crn.nearby})")
    if r.importances:
        console.print("importances: " + ", ".join(f"{k} {v:.2f}" for k, v in r.importances.items()))
    if not r.finished:
        console.print(f"{len(r.candidates)} of the study's candidates evaluated: run the same command to continue")
    elif r.verdict is None:
        console.print("no candidate beat the start on the search seed: nothing to write or judge")
    else:
        v = r.verdict
        console.print(f"verdict on seed {r.verdict_seed} (the search used {', '.join(map(str, r.search_seeds))}): "
                      f"{v.verdict}, {v.old:.4g} → {v.new:.4g} ({100 * (v.relative_change or 0):+.1f} %), "
                      f"{100 * v.confidence:g} % interval [{v.low:.3g}, {v.high:.3g}]")
        console.print(f"best revision: {r.revision} (store run {r.run_id})")
    console.print("report: " + ", ".join(str(p) for p in r.paths.values()))
