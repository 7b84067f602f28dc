"""`history`: a design's stored runs across its revisions, in commit order.

Rows come from the results store; the order is the design repository's commit
order (`git rev-list --topo-order`), falling back on commit time for commits no
longer reachable, and on the run order within a commit. Runs from a dirty tree
are marked: their numbers belong to no commit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lensmount.loop.provenance import commit_order
from lensmount.run.results import save_figure
from lensmount.run.store import RunRecord, Store, default_path


@dataclass(frozen=True)
class HistoryOptions:
    design: Path
    scene: str | None = None
    store: Path | None = None


def history(options: HistoryOptions) -> list[RunRecord]:
    """The stored runs of the design (and scene), oldest revision first."""
    design = Path(options.design)
    scene = Path(options.scene).stem if options.scene else None
    with Store(default_path(design, options.store)) as store:
        runs = store.runs(design_path=design, scene_name=scene)
    order = {c: i for i, c in enumerate(commit_order(design))}

    def key(r: RunRecord):
        position = order.get(r.git_commit or "", -1)
        return (r.git_commit_time or 0, position, r.id) if r.git_commit else (float("inf"), 0, r.id)

    return sorted(runs, key=key)


def write_history_plot(path: Path, runs: list[RunRecord], title: str = "") -> None:
    """Stray fraction per run with error bars (±2 std errors + bias bound), labelled by commit."""
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [r for r in runs if r.stray_fraction is not None]
    fig, ax = plt.subplots(figsize=(max(5.0, 0.6 * len(shown) + 2), 4.0), dpi=100)
    x = range(len(shown))
    err = [2 * (r.stray_fraction_std_error or 0.0) + (r.stray_fraction_bias_bound or 0.0) for r in shown]
    ax.errorbar(list(x), [r.stray_fraction for r in shown], yerr=err, fmt="o", capsize=3)
    ax.set_xticks(list(x), [label(r) for r in shown], rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("stray fraction (±2σ + bias bound)")
    ax.set_title(title or "stray fraction by revision", fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path)


def label(r: RunRecord) -> str:
    """Short commit with '*' for a dirty tree, or 'no git'."""
    if not r.git_commit:
        return f"run {r.id} (no git)"
    return r.git_commit[:8] + ("*" if r.git_dirty else "")


__all__ = ["HistoryOptions", "history", "write_history_plot", "label"]
