"""A finished run continued by more passes: where it lives on, and on which inputs.

A run is continued from its checkpoint in its own output folder (a store row's copy names that
folder), on the inputs it ran on: its design folder while that still holds them, else the
store's copy of them (`run.store.Store.restore_inputs`), so a run of an earlier revision takes
more passes after the folder has moved on (`compare --until-decided`, `watch`). A run is given
here as its folder and summary.json.
"""

from __future__ import annotations

import json
from pathlib import Path

from lensmount.errors import InputError
from lensmount.loop.prepare import read_inputs
from lensmount.loop.provenance import INPUTS_OF
from lensmount.loop.simulate import CHECKPOINT, Observer, SimulateOptions, SimulateResult, planned_input_hash, simulate
from lensmount.run.results import read_summary
from lensmount.run.store import ORIGIN, Store, default_path


def live_folder(folder: Path, summary: dict) -> Path:
    """Where the run goes on: its own output folder. A store row's copy (rows/ID) names it in
    `store.ORIGIN` and counts only while that folder still holds this very run (same checksum)."""
    origin = folder / ORIGIN
    if not origin.is_file():
        return folder
    live = Path(origin.read_text().strip())
    try:
        same = read_summary(live / "summary.json").get("sha256") == summary.get("sha256")
    except InputError:  # gone or damaged since: the copy stays what there is
        same = False
    return live if same else folder


def not_resumable(folder: Path, summary: dict, store: Path | None = None) -> str | None:
    """Why the run cannot take more passes (None: it can): no checkpoint, or neither its design folder
    nor the store's copy of its inputs holds what it ran on. store : --store (None: the design's)."""
    live = live_folder(folder, summary)
    if not (live / CHECKPOINT).is_file():
        return f"run {folder} has no checkpoint to continue from in {live}"
    inputs = inputs_of(folder, summary, store)
    return inputs if isinstance(inputs, str) else None


def inputs_of(folder: Path, summary: dict, store: Path | None = None) -> tuple[Path, Path] | str:
    """(design folder, scene file) holding the inputs the run ran on: its own folder while unchanged, else
    the store's copy of them; or why there are none."""
    prov = summary.get("provenance", {})
    if not prov.get("design_path") or not prov.get("scene_path"):
        return f"run {folder} does not say which design and scene made it"
    design, scene = Path(prov["design_path"]), Path(prov["scene_path"])
    if _holds(summary, design, scene):
        return design, scene
    with Store(_store_of(summary, store)) as kept:
        copy = kept.restore_inputs(prov.get("inputs", {}), summary.get("input_hash", ""),
                                   (INPUTS_OF, json.dumps(prov, indent=1)))
    if copy is not None and _holds(summary, copy, copy / prov["scene_input"]):
        return copy, copy / prov["scene_input"]
    return (f"the inputs of run {folder} changed since it ran ({design}, {scene.name}) and the store keeps no "
            "copy of them (a run of an older lensmount, or one run with --no-record)")


def _holds(summary: dict, design: Path, scene: Path) -> bool:
    """The design folder and scene still hash to the run's inputs."""
    if not design.is_dir() or not scene.is_file():
        return False
    sim = continued_options(summary, Path("."), 0, design, scene)
    try:
        return planned_input_hash(sim, *read_inputs(design, scene)) == summary.get("input_hash")
    except InputError:  # the folder no longer reads: not the run's inputs
        return False


def _store_of(summary: dict, store: Path | None) -> Path:
    """The store the run belongs to: --store, else its design folder's."""
    return default_path(summary.get("provenance", {}).get("design_path", "."), store)


def continued_options(summary: dict, out: Path, more: int, design: Path, scene: Path, workers: int = 0,
                      store: Path | None = None) -> SimulateOptions:
    """The options that continue the run (`summary`) in `out` by `more` passes on `design` and `scene`."""
    settings = summary.get("estimator_settings", {})
    return SimulateOptions(design, scene, method=summary.get("method", "bidirectional"), seed=summary.get("seed"),
                           out=out, passes=int(summary.get("passes", 0)) + more,
                           photons_per_pass=summary.get("photons_per_pass"),
                           samples_per_pixel=int(settings.get("samples_per_pixel", 1)),
                           view_map_pitch=int(settings.get("view_map_pitch", 1)),
                           alpha=float(summary.get("alpha", settings.get("alpha", 0.7))), workers=workers,
                           resume=True, store=_store_of(summary, store))


def continue_run(folder: Path, summary: dict, more: int, workers: int = 0, store: Path | None = None,
                 observer: Observer | None = None) -> SimulateResult:
    """The run continued from its checkpoint by `more` passes, on the inputs it ran on: its design folder
    while unchanged, else the store's copy of them (InputError when neither holds them)."""
    inputs = inputs_of(folder, summary, store)
    if isinstance(inputs, str):
        raise InputError(inputs, file=str(folder / "summary.json"), field="provenance",
                         valid="a run of this lensmount version recorded in the store, or its unchanged design")
    out = live_folder(folder, summary)
    return simulate(continued_options(summary, out, more, *inputs, workers=workers, store=store), observer)


__all__ = ["live_folder", "not_resumable", "inputs_of", "continued_options", "continue_run"]
