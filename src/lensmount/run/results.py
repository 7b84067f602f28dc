"""Writing a run's results: irradiance.exr, preview.png, summary.json — each atomically.

- `irradiance.exr`: float32 scanline image, channel `Y` = total normalised irradiance
  E/E_sun (E/E_ref for a source at a finite distance; header `lensmount_units`), plus one channel
  per contributing part (named after the part). Row 0 is the
  detector's −y edge (the array as the integrators produce it; header `lensmount_row0`).
- `preview.png`: false-colour log10(E/E_sun or E/E_ref) with a colour bar, detector axes in mm and
  the field of view outlined.
- `summary.json`: the numbers, never a NaN or Inf (`allow_nan=False`); unknowns are null.
- `report.html`: one self-contained page (images inline) for handing the run round.

Every file is written to a temporary name in the output folder and renamed into place,
so a reader never sees half a file and a crash leaves the previous result intact.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lensmount.analysis.passes import Accumulator
from lensmount.atomic import atomic_path, checksum_holds, with_checksum
from lensmount.errors import InputError
from lensmount.run.report import run_report, write_report


def _atomic(path, write) -> None:
    """Call write(tmp) then rename tmp onto path (lensmount.atomic)."""
    with atomic_path(path) as tmp:
        write(str(tmp))


def channel_name(part: str) -> str:
    """EXR channel name for a part: dots separate layers in EXR, so they become '_'."""
    return part.replace(".", "_") or "part"


def write_exr(path: str | os.PathLike, image: np.ndarray, per_part: np.ndarray, part_names: list[str],
              only_contributing: bool = True, unit: str = "E/E_sun") -> list[str]:
    """Write Y + one channel per part (parts with zero everywhere are left out when
    `only_contributing`), in `unit` (E/E_ref for a source at a finite distance). Returns the part channels written."""
    import OpenEXR  # lazy: keeps lensmount --help from loading OpenEXR

    path = Path(path)
    channels = {"Y": np.ascontiguousarray(np.nan_to_num(image, nan=0.0, posinf=0.0, neginf=0.0), np.float32)}
    written = []
    for name, layer in zip(part_names, per_part):
        if only_contributing and not np.any(layer):
            continue
        key = channel_name(name)
        if key == "Y":
            key = "part_Y"
        channels[key] = np.ascontiguousarray(np.nan_to_num(layer, nan=0.0, posinf=0.0, neginf=0.0), np.float32)
        written.append(name)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              "lensmount_row0": "-y", "lensmount_units": unit}

    def write(tmp):
        OpenEXR.File(header, channels).write(tmp)

    _atomic(path, write)
    return written


def read_exr(path: str | os.PathLike, sha256: str | None = None) -> dict[str, np.ndarray]:
    """Channels of an EXR file as float32 arrays (for tests and `compare`). InputError naming the
    file when it is damaged: it does not read, or its bytes disagree with `sha256` (the checksum
    summary.json keeps under `files`: EXR has none of its own, and a flipped bit reads as a pixel)."""
    import OpenEXR  # lazy: keeps lensmount --help from loading OpenEXR

    path = Path(path)
    try:
        if sha256 is not None and hashlib.sha256(path.read_bytes()).hexdigest() != sha256:
            raise ValueError("its bytes disagree with the checksum in summary.json")
        with OpenEXR.File(str(path)) as f:
            return {k: np.array(v.pixels) for k, v in f.channels().items()}
    except (OSError, ValueError, RuntimeError) as exc:
        raise InputError(f"the image is damaged and cannot be read ({exc})", file=str(path),
                         valid="irradiance.exr as `lensmount simulate` wrote it: simulate again (with --resume "
                               "while checkpoint.npz is there, the same numbers)") from None


@dataclass(frozen=True)
class PreviewScale:
    """How a preview maps irradiance to colour, so previews meant to be compared match.

    vmin, vmax : E/E_sun at the bottom and top of the log colour bar (0 < vmin ≤ vmax)
    block : pixels per side of the square blocks whose means are shown (1 = full resolution)
    """

    vmin: float
    vmax: float
    block: int = 1


def block_mean(image: np.ndarray, block: int) -> np.ndarray:
    """(ny/b, nx/b) means of b×b pixel blocks; b must divide both sides."""
    ny, nx = image.shape
    if block <= 1:
        return np.asarray(image, dtype=np.float64)
    if ny % block or nx % block:
        raise ValueError(f"block {block} does not divide the image {nx}×{ny}")
    return np.asarray(image, dtype=np.float64).reshape(ny // block, block, nx // block, block).mean(axis=(1, 3))


def preview_scale(images: list[np.ndarray], block: int = 1) -> PreviewScale:
    """One log colour scale covering every image (already block-averaged): from the 1st
    percentile of the lit pixels (at most 6 decades below the brightest) to the brightest."""
    lit = [np.asarray(i, dtype=np.float64)[np.isfinite(i) & (np.asarray(i) > 0)] for i in images]
    positive = np.concatenate([v.ravel() for v in lit]) if lit else np.zeros(0)
    if not positive.size:
        return PreviewScale(1e-12, 1e-11, block)  # nothing lit: any valid scale shows black
    hi = float(positive.max())
    lo = max(float(np.percentile(positive, 1)), hi * 1e-6)
    return PreviewScale(lo, hi if hi > lo else lo * 10.0, block)


def shared_scale(runs: list[tuple[np.ndarray, np.ndarray]], target_rel_error: float = 0.25) -> PreviewScale:
    """The scale for previews of runs meant to be compared: one block size (the coarsest any
    run needs to be readable, see `display_binning`) and one colour range over all of them.

    runs : [(mean image, std error image), ...], all of the same shape
    """
    shapes = {m.shape for m, _ in runs}
    if len(shapes) != 1:
        raise ValueError(f"runs with different detector pixels cannot share a preview: {sorted(shapes)}")
    block = max(display_binning(m, e, target_rel_error)[0] for m, e in runs)
    return preview_scale([block_mean(m, block) for m, _ in runs], block)


def _figure_extent(ax, extent_mm, field_radius_mm, field_half_size_mm) -> None:
    """Axes labels, the field of view outlined, and limits that show the whole outline."""
    from matplotlib.patches import Circle, Rectangle  # lazy: keeps lensmount --help from loading matplotlib

    if field_radius_mm:
        ax.add_patch(Circle((0, 0), field_radius_mm, fill=False, ec="cyan", lw=1, ls="--", label="field of view"))
    if field_half_size_mm:
        hx, hy = field_half_size_mm
        ax.add_patch(Rectangle((-hx, -hy), 2 * hx, 2 * hy, fill=False, ec="cyan", lw=1, label="field of view"))
    if field_radius_mm or field_half_size_mm:
        ax.legend(loc="upper right", fontsize=7)
        # Show the whole outline even where the field is larger than the detector.
        reach = max(field_radius_mm or 0.0, *(field_half_size_mm or (0.0,)))
        x0, x1, y0, y1 = extent_mm
        ax.set_xlim(min(x0, -1.02 * reach), max(x1, 1.02 * reach))
        ax.set_ylim(min(y0, -1.02 * reach), max(y1, 1.02 * reach))
        ax.set_facecolor("0.85")
    ax.set_xlabel("x on detector (mm)")
    ax.set_ylabel("y on detector (mm)")


def save_figure(fig, path) -> None:
    """Save a matplotlib figure as PNG atomically and close it."""
    import matplotlib.pyplot as plt  # lazy: keeps lensmount --help from loading matplotlib

    def write(tmp):
        fig.savefig(tmp, format="png")

    try:
        _atomic(Path(path), write)
    finally:
        plt.close(fig)


def write_preview(path: str | os.PathLike, image: np.ndarray, extent_mm: tuple[float, float, float, float],
                  field_radius_mm: float | None = None, field_half_size_mm: tuple[float, float] | None = None,
                  title: str = "", scale: PreviewScale | None = None, unit: str = "E/E_sun") -> None:
    """False-colour log10 preview with colour bar and the field of view outlined.

    image : full-resolution irradiance in `unit` (E/E_sun; E/E_ref for a source at a finite distance);
        shown as `scale.block`-pixel block means
    extent_mm : (x_min, x_max, y_min, y_max) of the detector
    field_radius_mm : image height of the full field (circle), if known
    field_half_size_mm : half width/height of a rectangular field, if known
    scale : colour range and block size; None fits them to this image alone. Pass one
        scale (from `shared_scale`) to every preview meant to be compared.
    """
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    img = np.nan_to_num(np.asarray(image, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    scale = scale or preview_scale([img])
    img = block_mean(img, scale.block)
    fig, ax = plt.subplots(figsize=(6.4, 5.2), dpi=100)
    if np.any(img > 0):
        shown = np.log10(np.clip(img, scale.vmin, None))
        im = ax.imshow(shown, origin="lower", extent=extent_mm, cmap="inferno", vmin=math.log10(scale.vmin),
                       vmax=math.log10(scale.vmax), interpolation="nearest")
        fig.colorbar(im, ax=ax, label=f"log10 {unit}")
    else:
        im = ax.imshow(np.zeros_like(img), origin="lower", extent=extent_mm, cmap="inferno", vmin=0, vmax=1)
        fig.colorbar(im, ax=ax, label=f"{unit} (no stray light reached the detector)")
    _figure_extent(ax, extent_mm, field_radius_mm, field_half_size_mm)
    if scale.block > 1:
        title = (title + " · " if title else "") + f"{scale.block}×{scale.block}-pixel means"
    ax.set_title(title or "stray irradiance", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


def write_difference(path: str | os.PathLike, new: np.ndarray, old: np.ndarray,
                     extent_mm: tuple[float, float, float, float], scale: PreviewScale,
                     field_radius_mm: float | None = None, field_half_size_mm: tuple[float, float] | None = None,
                     title: str = "") -> np.ndarray:
    """Signed difference new − old in E/E_sun, block means as in `scale`, on a diverging
    colour bar symmetric about zero (red: brighter in new, blue: darker). The colour
    limit is the largest |difference|, at least `scale.vmin` so that noise-free equal
    runs show white rather than an empty range. Returns the block-mean difference."""
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    clean = [np.nan_to_num(np.asarray(a, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0) for a in (new, old)]
    if clean[0].shape != clean[1].shape:
        raise ValueError(f"cannot subtract images of shapes {clean[0].shape} and {clean[1].shape}")
    diff = block_mean(clean[0], scale.block) - block_mean(clean[1], scale.block)
    limit = max(float(np.abs(diff).max()) if diff.size else 0.0, scale.vmin)
    fig, ax = plt.subplots(figsize=(6.4, 5.2), dpi=100)
    im = ax.imshow(diff, origin="lower", extent=extent_mm, cmap="RdBu_r", vmin=-limit, vmax=limit,
                   interpolation="nearest")
    fig.colorbar(im, ax=ax, label="Δ E/E_sun (new − old)")
    _figure_extent(ax, extent_mm, field_radius_mm, field_half_size_mm)
    suffix = f"{scale.block}×{scale.block}-pixel means" if scale.block > 1 else ""
    ax.set_title(" · ".join(t for t in (title or "difference new − old", suffix) if t), fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)
    return diff


def display_binning(mean: np.ndarray, std_error: np.ndarray, target_rel_error: float = 0.25,
                    max_bin: int = 60) -> tuple[int, np.ndarray]:
    """The smallest square bin b (dividing both image sides) whose lit bins reach the target error.

    A short run leaves isolated lit pixels (each pixel's own error is ~100 %); the
    preview then shows b×b-pixel means so the distribution can be read. Bins are
    treated as sums of independent pixels (photon sharing makes that optimistic,
    which only errs toward finer bins). The EXR always keeps full resolution.
    Returns (b, (ny/b, nx/b) binned mean).
    """
    ny, nx = mean.shape
    sizes = [b for b in range(1, min(max_bin, ny, nx) + 1) if ny % b == 0 and nx % b == 0]
    binned = mean
    for b in sizes:
        total = mean.reshape(ny // b, b, nx // b, b).sum(axis=(1, 3))
        var = (std_error**2).reshape(ny // b, b, nx // b, b).sum(axis=(1, 3))
        lit = total > 0
        binned = total / (b * b)
        if not lit.any():
            return 1, mean
        if float(np.median(np.sqrt(var[lit]) / total[lit])) <= target_rel_error:
            return b, binned
    return sizes[-1], binned


def write_summary(path: str | os.PathLike, summary: dict) -> None:
    """JSON with sorted keys, refusing NaN/Inf (a bug upstream, never silently written), with the
    checksum `read_summary` checks."""
    text = json.dumps(with_checksum(summary), indent=2, sort_keys=True, allow_nan=False)

    def write(tmp):
        Path(tmp).write_text(text + "\n")

    _atomic(Path(path), write)


def read_summary(path: str | os.PathLike, field: str | None = None) -> dict:
    """A summary.json as written; InputError naming it when it is missing, damaged (does not parse, or
    its checksum disagrees: a flipped digit) or not a summary."""
    path = Path(path)
    try:
        summary = json.loads(path.read_bytes())
    except FileNotFoundError:
        raise InputError("not a results folder (no summary.json)", file=str(path.parent), field=field,
                         valid="a folder written by `lensmount simulate`") from None
    except (OSError, ValueError) as exc:
        summary, problem = None, f"it does not parse ({exc})"
    else:
        problem = "its checksum disagrees with its content"
    if summary is None or not checksum_holds(summary):
        raise InputError(f"summary.json is damaged: {problem}", file=str(path), field=field,
                         valid="a summary.json as `lensmount simulate` wrote it: simulate again (with --resume "
                               "while its checkpoint.npz is there, the same numbers)")
    return summary


def write_run(out_dir: str | os.PathLike, accumulator: Accumulator, summary: dict, *,
              extent_mm: tuple[float, float, float, float] | None = None,
              field_radius_mm: float | None = None,
              field_half_size_mm: tuple[float, float] | None = None) -> dict[str, Path]:
    """Write irradiance.exr, preview.png, summary.json and report.html into out_dir. Returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ny, nx = accumulator.sum_image.shape
    if extent_mm is None:
        extent_mm = (-nx / 2, nx / 2, -ny / 2, ny / 2)
    paths = {"exr": out / "irradiance.exr", "png": out / "preview.png", "json": out / "summary.json",
             "html": out / "report.html"}
    # the source's units: E/E_sun, or E/E_ref for an object at a finite distance (summary's units)
    unit = summary.get("units", {}).get("irradiance", "E/E_sun").split(" ")[0]
    write_exr(paths["exr"], accumulator.mean_image, accumulator.mean_parts, accumulator.part_names, unit=unit)
    summary["files"] = {paths["exr"].name: hashlib.sha256(paths["exr"].read_bytes()).hexdigest()}  # read_exr checks
    title = f"{summary.get('method', '')} · {summary.get('passes', accumulator.n)} passes"
    scale = shared_scale([(accumulator.mean_image, accumulator.std_error_image)])
    if scale.block > 1:
        title += f" · EXR: full {nx}×{ny}"
    write_preview(paths["png"], accumulator.mean_image, extent_mm, field_radius_mm, field_half_size_mm, title,
                  scale=scale, unit=unit)
    write_summary(paths["json"], summary)
    write_report(paths["html"], run_report(summary, {"stray irradiance on the detector": paths["png"]}))
    return paths


__all__ = ["write_run", "display_binning", "PreviewScale", "preview_scale", "shared_scale", "block_mean",
           "write_difference", "save_figure", "write_exr", "read_exr", "write_preview", "write_summary", "read_summary", "channel_name"]
