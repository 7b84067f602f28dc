"""`lensmount simulate DESIGN --scene SCENE`: parses, calls lensmount.loop.simulate, prints.

While it runs it shows the current stray fraction with its error, the error trend
and an ETA to the target: a rich progress bar on a terminal, one plain line per
pass when stdout is a file or a pipe (logs stay readable).
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.errors import InputError
from lensmount.loop.progress import PassStatus
from lensmount.loop.simulate import QUICK, Observer, SimulateOptions, simulate as run_simulation
from lensmount.loop.progress import next_halving_s
from lensmount.run.executor import WORKER_WAIT_S


QUICK_HELP = (f"Iterate: stop at {100 * QUICK.target_rel_error:g} % (after {QUICK.min_passes} passes) or "
              f"{QUICK.time_s:g} s of tracing, instead of the scene's run table. Only the length differs: the "
              "same test condition and input hash as a full run, so the store and compare take it as a shorter "
              "run of the same test (compare's interval is wider for it), and --resume without --quick "
              "continues it to the scene's target.")


def print_plan(console, block: dict | None) -> None:
    """The plan block of summary.json: what ran, what was skipped and why, seconds per phase."""
    if not block:
        return
    table = Table(title="plan: what ran, what was skipped and why", title_justify="left", show_header=False)
    table.add_column(style="bold")
    table.add_column()
    for item in block["ran"]:
        share = item.get("edge_flux_share")
        table.add_row(item["what"], item["why"] + (" · edge light by component: " + ", ".join(
            f"{c} {100 * v:.1f} %" for c, v in share.items()) if share else ""))
        if item.get("note"):  # e.g. the pilot's ring missed the lit edge and was mended (`plan.edge_flux_components`)
            table.add_row("", f"note: {item['note']}")
        if item.get("warning"):
            table.add_row("", f"warning: {item['warning']}", style="yellow")
    for item in block["skipped"]:
        table.add_row(f"{item['what']} (skipped)", item["why"], style="dim")
    for phase, seconds in block.get("wall_time_s", {}).items():
        table.add_row(f"wall time: {phase}", f"{seconds:.2f} s")
    for phase, seconds in block["time_s"].items():
        table.add_row(f"time: {phase}", f"{seconds:.2f} s, summed over passes and workers")
    console.print(table)


def duration(seconds: float | None, unknown: str = "—") -> str:
    """A time as an engineer reads it: s below 90 s, min below 90 min, else h."""
    if seconds is None:
        return unknown
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def describe(s: PassStatus) -> str:
    """One line: passes, photons, value ± error, relative error, its trend, ETA."""
    value = f"{s.value:.4g}" + (f" ± {s.std_error:.2g}" if s.std_error is not None else "")
    rel = f"{100 * s.rel_error:.2f} %" if s.rel_error < float("inf") else \
        "unknown" + (f" ({s.rel_error_unknown})" if s.rel_error_unknown else "")
    text = f"pass {s.passes} · {s.photons:,} photons · {s.elapsed_s:.0f} s · stray fraction {value} · rel. error {rel}"
    if s.error_slope is not None:
        text += f" (∝ t^{s.error_slope:+.2f}" + (f" ± {s.error_slope_se:.2f})" if s.error_slope_se else ")")
    if s.largest_over_median is not None:
        text += f" · largest pass {s.largest_over_median:.2f}× median"
    if s.heavy_tail:
        text += " (one pass dominates: heavy tail, not converged)"
    if s.target_rel_error is not None:
        text += f" · target {100 * s.target_rel_error:g} % " + (f"in ~{duration(s.eta_s)}" if s.eta_s is not None
                                                                else "in a time not known yet")
    return text


class TerminalObserver(Observer):
    """Stages and passes on stderr: rich on a terminal, one line per event otherwise."""

    HEARTBEAT_S = 10.0  # while the first pass runs (tracer, pilot, view map, photons), a line this often

    def __init__(self, live: bool):
        self.live = live
        self.console = Console(stderr=True)
        self.bar = None
        self.tasks: dict[str, int] = {}
        self.step_started: dict[str, float] = {}
        self.first_pass: threading.Event | None = None

    def stage(self, text: str) -> None:
        self._close()
        self.step_started.clear()
        self._say(text)
        if text.startswith("tracing:"):
            self._wait_for_first_pass(time.monotonic(), bidirectional="bidirectional" in text)

    def _say(self, text: str) -> None:
        if self.live:
            self.console.print(f"[bold]·[/bold] {text}", markup=True)
        else:
            typer.echo(text, err=True)

    def _wait_for_first_pass(self, start: float, bidirectional: bool) -> None:
        """A line every HEARTBEAT_S until the first pass is merged: it builds the tracer and, in the
        bidirectional method, runs the pilot and the view map before its photons, and was silent for minutes."""
        self.first_pass = done = threading.Event()
        extra = ", aims the photons (pilot) and builds the view map" if bidirectional else ""

        def beat():
            while not done.wait(self.HEARTBEAT_S):
                self._say(f"  pass 1 still running ({time.monotonic() - start:.0f} s): the first pass also loads "
                          f"the tracer{extra}")

        threading.Thread(target=beat, daemon=True).start()

    def build_step(self, step: str, done: int, total: int) -> None:
        started = self.step_started.setdefault(step, time.monotonic())
        if not self.live:
            if done == total:
                typer.echo(f"  CAD {step}: done ({time.monotonic() - started:.1f} s)", err=True)
            return
        bar = self._bar()
        if step not in self.tasks:
            self.tasks[step] = bar.add_task(f"CAD {step}", total=total, info="")
        bar.update(self.tasks[step], completed=done, total=total)

    def pass_done(self, s: PassStatus) -> None:
        if self.first_pass is not None:
            self.first_pass.set()
        if not self.live:
            typer.echo(describe(s), err=True)
            return
        bar = self._bar()
        if "passes" not in self.tasks:
            self.tasks["passes"] = bar.add_task("passes", total=s.max_passes, info="")
        bar.update(self.tasks["passes"], completed=s.passes, total=s.max_passes, info=describe(s).split(" · ", 1)[1])

    def _bar(self):
        if self.bar is None:
            self.bar = Progress(TextColumn("{task.description:<16}"), BarColumn(bar_width=24),
                                TextColumn("{task.fields[info]}"), TimeElapsedColumn(), console=self.console)
            self.bar.start()
        return self.bar

    def _close(self) -> None:
        if self.bar is not None:
            self.bar.stop()
            self.bar = None
            self.tasks = {}

    def close(self) -> None:
        if self.first_pass is not None:
            self.first_pass.set()
        self._close()


def observed(call, *args, kind: type[TerminalObserver] = TerminalObserver):
    """call(*args, observer) with progress on stderr (an observer of `kind`); an InputError becomes the
    one-paragraph exit 2."""
    observer = kind(live=sys.stderr.isatty())
    try:
        return call(*args, observer)
    except InputError as error:
        observer.close()
        fail(error)
    finally:
        observer.close()


@COMMANDS.register("simulate", CommandLine)
def simulate(
    design: Path = typer.Argument(..., help="Design folder (lens.toml or lens.zmx, mount.toml, scenes/)."),
    scene: Path = typer.Option(..., "--scene", help="Scene: a name from DESIGN/scenes/ or a scene file."),
    method: str = typer.Option("bidirectional", "--method", help="bidirectional | forward | a plug-in integrator."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Run seed, >= 0 (default: the scene's run.seed)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Output folder (default out/<scene name>)."),
    photons: Optional[int] = typer.Option(None, "--photons", help="Stop after this many photons in total."),
    time_s: Optional[float] = typer.Option(None, "--time", help="Stop after this many seconds (> 0)."),
    target_rel_error: Optional[float] = typer.Option(None, "--target-rel-error",
                                                     help="Stop when the stray fraction has this relative error."),
    passes: Optional[int] = typer.Option(None, "--passes", help="At most this many passes."),
    photons_per_pass: Optional[int] = typer.Option(None, "--photons-per-pass",
                                                   help="Photons per pass (default: the scene's run.photons)."),
    samples_per_pixel: int = typer.Option(1, "--samples-per-pixel", help="Backward samples per pixel per pass."),
    view_map_pitch: Optional[int] = typer.Option(
        None, "--view-map-pitch", help="Bidirectional: the view map samples blocks of N × N pixels a pass (default: "
                                       "the scene's run.view_map_pitch, else 1). N² fewer backward rays a pass for "
                                       "the same expected total and image; the image fills in over more passes."),
    alpha: float = typer.Option(0.7, "--alpha", help="Radius shrink parameter, 0 < alpha < 1."),
    workers: int = typer.Option(0, "--workers", help="Worker processes (0 = one per core)."),
    resume: bool = typer.Option(False, "--resume", help="Continue from OUT/checkpoint.npz (none there: start from the first "
                                                       "pass, as a batch retry of a run that kept nothing)."),
    geometry: Optional[Path] = typer.Option(None, "--geometry",
                                            help="Regenerate's output folder to reuse (default DESIGN/build)."),
    store: Optional[Path] = typer.Option(None, "--store", help="Results store (default DESIGN/.lensmount/runs.sqlite, "
                                                               "or $LENSMOUNT_STORE)."),
    no_record: bool = typer.Option(False, "--no-record", help="Do not add this run to the results store."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", envvar="LENSMOUNT_SCHEDULER",
                                            help="Run the passes on this Dask scheduler (tcp://HOST:8786); "
                                                 "see docs/scale.md."),
    cluster: Optional[str] = typer.Option(None, "--cluster", help="Start a Dask LocalCluster: local:N processes."),
    worker_wait: float = typer.Option(WORKER_WAIT_S, "--worker-wait",
                                      help="Seconds a Dask run with no worker left waits for one; then it writes "
                                           "its checkpoint and exits 75, for a batch script to retry with --resume."),
    glass_catalog: GlassCatalogs = [],
    quick: bool = typer.Option(False, "--quick", help=QUICK_HELP),
) -> None:
    """Simulate the stray light on the detector: irradiance.exr, preview.png, summary.json, a row in the store.

    The mount geometry comes from DESIGN/build (what `lensmount regenerate DESIGN` writes),
    rebuilt only when the design changed. Progress goes to stderr. How long: the rules given here
    (--photons, --time, --target-rel-error, --passes), else --quick, else the scene's run table:
    its target_rel_error after 8 passes, capped by its time_s (default 600 s) and its passes.
    Before tracing it says about how long that will take (from a stored run of the scene, else the
    first passes), and the progress line refines it.
    """
    options = SimulateOptions(design, scene, method, seed, out, photons, time_s, target_rel_error, passes,
                              photons_per_pass, samples_per_pixel, view_map_pitch, alpha, workers, resume, geometry,
                              store, not no_record, list(sys.argv), scheduler, cluster, worker_wait, quick)
    result = observed(run_simulation, options)
    print_summary(result.summary, result.paths)
    if result.stopped_short:
        typer.echo(f"note: {result.stopped_short}", err=True)
    typer.echo(f"one more halving of the error: about {duration(next_halving_s(result.summary['time_s']))} more")
    if result.run_id is not None:
        typer.echo(f"recorded as run {result.run_id} in {result.store_path}")
    if result.interrupted:
        typer.echo(result.stop_message(), err=True)
        raise typer.Exit(code=result.exit_code)


def print_summary(summary: dict, paths: dict) -> None:
    """The figures an engineer reads first: the stray level with its error bar, then who carries it."""
    def pm(value, error):
        return f"{value:.4g} ± {error:.2g}" if error is not None else f"{value:.4g}"

    console = Console()
    for warning in summary.get("warnings", []):
        console.print(f"warning: {warning}", style="yellow", markup=False)  # "[checks]" is text
    if summary.get("no_light_enters"):
        console.print(f"no light enters: {summary['no_light_enters']}", style="yellow")
    if (summary.get("tail") or {}).get("note"):
        console.print(f"warning: {summary['tail']['note']}", style="yellow", markup=False)
    table = Table(title=f"{summary['method']} · {summary['passes']} passes · {summary['photons']:,} photons "
                        f"· {summary['time_s']:.1f} s", title_justify="left", show_header=False)
    table.add_column(style="bold")
    table.add_column(justify="right")
    upper = summary.get("stray_fraction_upper_bound")
    if upper is not None:
        table.add_row("stray fraction", f"no signal: < {upper:.2g} (95 %, no photon of "
                                        f"{summary['photons']:,} reached the detector)")
    else:
        table.add_row("stray fraction", pm(summary["stray_fraction"], summary.get("stray_fraction_std_error")))
    bias = summary.get("stray_fraction_bias_bound")
    if bias:
        table.add_row("kernel bias (bound)", f"± {bias:.2g}")
    if summary.get("stray_fraction_bias_unbounded"):
        table.add_row("kernel bias", f"cannot be bounded: {summary['stray_fraction_bias_unbounded']}")
    allowance, tail = summary.get("stray_fraction_tail_allowance"), summary.get("tail") or {}
    if allowance:  # the warning is printed above only when the allowance is a notable share of the ±
        index = f", x^-{tail['terms_tail_index']:.2f}" if tail.get("terms_tail_index") is not None else ""
        table.add_row("of the ±, tail allowance", f"{allowance:.2g} (the largest terms' tail{index}"
                      + ("; see the warning)" if tail.get("note") else ")"))
    if tail.get("terms_unbounded"):
        table.add_row("error bar", "none: the terms' tail has no bound (see the warning)")
    rel = summary.get("stray_fraction_rel_error")
    table.add_row("relative error (std + bias)", f"{100 * rel:.2f} %" if rel is not None else "—")
    drift = summary.get("stray_fraction_drift")
    if drift is not None:
        p = summary.get("stray_fraction_drift_p")
        table.add_row("radius drift (2nd half vs 1st)", f"{100 * drift:+.1f} %" + (f" (p = {p:.2f})" if p is not None else ""))
    if tail.get("largest_over_median") is not None:
        table.add_row("largest pass / median", f"{tail['largest_over_median']:.2f}"
                      + (" (one pass dominates: not converged)" if tail.get("heavy") else ""))
    unit = summary["units"]["irradiance"].split(" ")[0]  # E/E_sun, or E/E_ref for a source at a finite distance
    table.add_row(f"peak irradiance {unit.replace('E/', '/ ')}", f"{summary['peak_irradiance']:.4g}")
    table.add_row("effects", ", ".join(summary["effects"]) + (f" (skipped: {', '.join(summary['effects_skipped'])})"
                                                               if summary["effects_skipped"] else ""))
    if summary.get("lost_flux"):
        table.add_row("lost flux (mm²)", f"{summary['lost_flux']:.3g}")
    console.print(table)
    print_plan(console, summary.get("plan"))
    parts = sorted(((v["fraction"], name, v["std_error"]) for name, v in summary["per_part"].items()
                    if v["fraction"] > 0), reverse=True)
    if parts:
        by_part = Table(title="stray fraction by part (last scattering surface)", title_justify="left")
        by_part.add_column("part")
        by_part.add_column("fraction", justify="right")
        by_part.add_column("share", justify="right")
        total = sum(f for f, _, _ in parts)
        for fraction, name, error in parts[:10]:
            by_part.add_row(name, pm(fraction, error), f"{100 * fraction / total:.1f} %")
        if len(parts) > 10:
            by_part.add_row(f"… {len(parts) - 10} more", "", "")
        console.print(by_part)
    top = (summary.get("top_paths") or {}).get("paths", [])[:3]
    if top:
        by_path = Table(title="leading stray paths (all: lensmount paths OUT --faces)", title_justify="left")
        by_path.add_column("events, in order")
        by_path.add_column("fraction", justify="right")
        for row in top:
            by_path.add_row(" → ".join(e["name"] for e in row["events"]), pm(row["fraction"], row["std_error"]))
        console.print(by_path)
    console.print("wrote " + ", ".join(str(p) for p in paths.values()))
