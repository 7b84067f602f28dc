"""`lensmount watch`: the loop kept warm, from a saved edit to a verdict.

One long-lived process watches the design folder. When a file of the design is saved (lens,
mount.toml, finishes, user templates, STEP parts, the scene) it regenerates what changed (the CAD
cache rebuilds only the parts whose inputs changed), simulates the scene and judges the result
against the baseline, progressively: a first look after the QUICK preset's run (loop.simulate), then
`compare --until-decided`'s looks, each adding the passes that would decide it. The baseline: by default the design as it was when `watch` started, or a stored run
(`against`: last, best or a git revision). The CAD kernel, the compiled tracer kernels and
the imports are paid for once, at start: the design's parts are built into this process then
(`loop.regenerate.warm`), so an edit pays for the parts it changed; worker processes are forked
from this warm process. A verdict is said as soon as it is reached; the comparison's images and
report follow before the folder is watched again.

A revision that does not build (an InputError) is said in one paragraph and watching goes on:
the next save is tried again. Each verdict is written to `OUT/watch.html`, a page that reloads
itself every few seconds, beside the comparison's own report.html.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from datetime import datetime
from pathlib import Path
from typing import Callable, Iterator

from lensmount.analysis.compare import UNDECIDED
from lensmount.errors import InputError
from lensmount.loop.compare import (CompareOptions, CompareResult, Run, compare, obtain, plan_current, verdict_sentence,
                                   write_comparison)
from lensmount.loop.regenerate import warm
from lensmount.loop.simulate import Observer
from lensmount.run.report import esc, page, section, table_block, write_report

# Folders of a design that are outputs, not inputs: saving into them is no edit.
NOT_INPUTS = frozenset({"build", ".lensmount", "out", "__pycache__", ".git"})
REFRESH_S = 3


@dataclass(frozen=True)
class WatchOptions:
    """design, scene : what to watch and simulate; against : None (the design when watching
    starts) or a stored run (last, best, a git revision); tolerance, confidence : the verdict's;
    time_s, passes, photons_per_pass, workers : each revision's first look (unset: the QUICK preset; the
    baseline, when simulated: the scene's [run]); budget_s : further tracing per revision until decided;
    out : watch.html and the comparisons (default DESIGN/.lensmount/watch); poll_s : how often the
    files are looked at; settle_s : how long they must stay unchanged (editors save in steps)."""

    design: Path
    scene: str
    against: str | None = None
    tolerance: float = 0.05
    confidence: float = 0.99
    time_s: float | None = None
    passes: int | None = None
    photons_per_pass: int | None = None
    workers: int = 0
    store: Path | None = None
    out: Path | None = None
    poll_s: float = 0.5
    settle_s: float = 0.3
    budget_s: float = 600.0


@dataclass(frozen=True)
class Revision:
    """One judged save: which files changed, the comparison (None when it did not build) and why. The
    verdict comes first: the comparison's images and report (`result.paths`) are written when the caller
    asks for the next revision, before the folder is watched again."""

    number: int
    changed: tuple[str, ...]
    result: CompareResult | None
    error: str | None
    seconds: float


def snapshot(design: Path) -> dict[str, tuple[int, int]]:
    """(mtime ns, size) of every input file of the design folder, by path relative to it."""
    design = Path(design)
    files = {}
    for path in design.rglob("*"):
        rel = path.relative_to(design)
        if any(part in NOT_INPUTS or part.startswith(".") for part in rel.parts) or not path.is_file():
            continue
        try:
            st = path.stat()
        except FileNotFoundError:  # removed between the listing and the look (an editor's swap file)
            continue
        files[str(rel)] = (st.st_mtime_ns, st.st_size)
    return files


def changed_files(before: dict, after: dict) -> tuple[str, ...]:
    """Files added, removed or modified between two snapshots, sorted."""
    return tuple(sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k)))


def wait_for_edit(design: Path, before: dict, poll_s: float, settle_s: float,
                  sleep: Callable[[float], None] = time.sleep) -> tuple[dict, tuple[str, ...]]:
    """Block until the design's files differ from `before` and then stay unchanged for settle_s."""
    while True:
        sleep(poll_s)
        now = snapshot(design)
        if now != before:
            while True:  # an editor may write a file in several steps
                sleep(settle_s)
                later = snapshot(design)
                if later == now:
                    return now, changed_files(before, now)
                now = later


def watch(options: WatchOptions, observer: Observer | None = None,
          wait: Callable[[Path, dict], tuple[dict, tuple[str, ...]]] | None = None) -> Iterator[Revision]:
    """The baseline first (revision 0), then one Revision per saved edit, for as long as the caller
    iterates (the CLI: until Ctrl-C). `wait(design, snapshot)` blocks until an edit (tests pass
    their own)."""
    o = options
    design = Path(o.design)
    if not design.is_dir():
        raise InputError("design folder not found", file=str(design), field="DESIGN",
                         valid="a folder with lens.toml or lens.zmx and mount.toml")
    wait = wait or (lambda d, before: wait_for_edit(d, before, o.poll_s, o.settle_s))
    out = Path(o.out) if o.out is not None else design / ".lensmount" / "watch"
    settings = CompareOptions(design, scene=o.scene, against=o.against, tolerance=o.tolerance,
                              confidence=o.confidence, store=o.store, workers=o.workers, passes=o.passes,
                              photons_per_pass=o.photons_per_pass, time_s=o.time_s, budget_s=o.budget_s)
    # a revision: a quick first look unless its length is given, then looks until decided
    judging = replace(settings, until_decided=True, quick=o.time_s is None and o.passes is None)
    history: list[Revision] = []
    files = snapshot(design)
    baseline: Run | None = None
    if o.against is None:  # the design as it is now; stored when an identical run exists
        start = time.perf_counter()
        baseline = obtain(plan_current(design, o.scene, settings, "old"), observer)
        warm(design)  # the CAD kernel and every part kept in this process: an edit rebuilds only what it changed
        first = Revision(0, (), None, None, time.perf_counter() - start)
        history.append(first)
        write_watch_page(out, design, baseline, history)
        yield first
    number = len(history)
    changed: tuple[str, ...] = ()
    while True:
        if number > 0 or o.against is None:
            files, changed = wait(design, files)
        start = time.perf_counter()
        target = out / f"revision-{number:03d}"
        try:
            if baseline is None:
                if number == 0:  # watching starts with this look: the CAD kept from here on (as for a baseline)
                    warm(design)
                result = compare(replace(judging, out=target), observer, write=False)
            else:
                new = obtain(plan_current(design, o.scene, judging), observer)
                result = compare(replace(judging, a=baseline.folder, b=new.folder, scene=None, against=None,
                                         out=target), observer, write=False)
            revision = Revision(number, changed, result, None, time.perf_counter() - start)
        except InputError as error:  # the edit does not build: say so and keep watching
            revision = Revision(number, changed, None, error.paragraph(), time.perf_counter() - start)
        history.append(revision)
        write_watch_page(out, design, baseline, history)
        yield revision
        if revision.result is not None:  # the verdict is out: now its images and report.html (seconds of matplotlib)
            r = revision.result
            r.paths = write_comparison(target, r.old, r.new, r)
            write_watch_page(out, design, baseline, history)
        number += 1


def write_watch_page(out: Path, design: Path, baseline: Run | None, history: list[Revision]) -> Path:
    """watch.html: the latest verdict first, then every revision judged so far; reloads itself."""
    rows = []
    for r in reversed(history):
        if r.number == 0:
            what = "baseline: the design when watching began"
        elif r.error is not None:
            what = f"did not build: {r.error}"
        else:  # an undecided verdict with why, and what would decide it
            v = r.result.verdict
            what = verdict_sentence(v) + (f" — {r.result.stopped or v.note}" if v.verdict == UNDECIDED else "")
        html = r.result.paths.get("html") if r.result is not None else None
        report = str(Path(html).relative_to(out)) if html and Path(html).is_relative_to(out) else str(html or "")
        rows.append([r.number, ", ".join(r.changed) or "—", what, f"{r.seconds:.1f}", report])
    base = f"baseline run: {baseline.folder}" if baseline is not None else "baseline: the store (--against)"
    blocks = [f"<p>{esc(str(design))} · {esc(base)} · updated {datetime.now():%H:%M:%S}</p>",
              section("Revisions, newest first",
                      table_block(["#", "files changed", "verdict", "seconds", "report"], rows))]
    return write_report(out / "watch.html", page("lensmount watch", blocks, refresh_s=REFRESH_S))


__all__ = ["WatchOptions", "Revision", "watch", "snapshot", "changed_files", "wait_for_edit", "write_watch_page"]
