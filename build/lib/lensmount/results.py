"""Writing a run's results: irradiance.exr, preview.png, summary.json — each atomically.

- `irradiance.exr`: float32 scanline image, channel `Y` = total normalised irradiance
  E/E_sun, plus one channel per contributing part (named after the part). Row 0 is the
  detector's −y edge (the array as the integrators produce it; header `lensmount_row0`).
- `preview.png`: false-colour log10(E/E_sun) with a colour bar, detector axes in mm and
  the field of view outlined.
- `summary.json`: the numbers, never a NaN or Inf (`allow_nan=False`); unknowns are null.

Every file is written to a temporary name in the output folder and renamed into place,
so a reader never sees half a file and a crash leaves the previous result intact.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from lensmount.analysis.passes import Accumulator
from lensmount.atomic import atomic_path


def _atomic(path, write) -> None:
    """Call write(tmp) then rename tmp onto path (lensmount.atomic)."""
    with atomic_path(path) as tmp:
        write(str(tmp))


def channel_name(part: str) -> str:
    """EXR channel name for a part: dots separate layers in EXR, so they become '_'."""
    return part.replace(".", "_") or "part"


def write_exr(path: str | os.PathLike, image: np.ndarray, per_part: np.ndarray, part_names: list[str],
              only_contributing: bool = True) -> list[str]:
    """Write Y + one channel per part (parts with zero everywhere are left out when
    `only_contributing`). Returns the part channels written."""
    import OpenEXR

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
              "lensmount_row0": "-y", "lensmount_units": "E/E_sun"}

    def write(tmp):
        OpenEXR.File(header, channels).write(tmp)

    _atomic(path, write)
    return written


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Channels of an EXR file as float32 arrays (for tests and `compare`)."""
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        return {k: np.array(v.pixels) for k, v in f.channels().items()}


def write_preview(path: str | os.PathLike, image: np.ndarray, extent_mm: tuple[float, float, float, float],
                  field_radius_mm: float | None = None, field_half_size_mm: tuple[float, float] | None = None,
                  title: str = "") -> None:
    """False-colour log10 preview with colour bar and the field of view outlined.

    extent_mm : (x_min, x_max, y_min, y_max) of the detector
    field_radius_mm : image height of the full field (circle), if known
    field_half_size_mm : half width/height of a rectangular field, if known
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    img = np.nan_to_num(np.asarray(image, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    positive = img[img > 0]
    fig, ax = plt.subplots(figsize=(6.4, 5.2), dpi=100)
    if positive.size:
        hi = float(positive.max())
        lo = max(float(np.percentile(positive, 1)), hi * 1e-6)
        shown = np.log10(np.clip(img, lo, None))
        im = ax.imshow(shown, origin="lower", extent=extent_mm, cmap="inferno", vmin=math.log10(lo),
                       vmax=math.log10(hi) if hi > lo else math.log10(lo) + 1, interpolation="nearest")
        fig.colorbar(im, ax=ax, label="log10 E/E_sun")
    else:
        im = ax.imshow(np.zeros_like(img), origin="lower", extent=extent_mm, cmap="inferno", vmin=0, vmax=1)
        fig.colorbar(im, ax=ax, label="E/E_sun (no stray light reached the detector)")
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
    ax.set_title(title or "stray irradiance", fontsize=9)
    fig.tight_layout()

    def write(tmp):
        fig.savefig(tmp, format="png")

    try:
        _atomic(Path(path), write)
    finally:
        plt.close(fig)


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
    """JSON with sorted keys, refusing NaN/Inf (a bug upstream, never silently written)."""
    text = json.dumps(summary, indent=2, sort_keys=True, allow_nan=False)

    def write(tmp):
        Path(tmp).write_text(text + "\n")

    _atomic(Path(path), write)


def write_run(out_dir: str | os.PathLike, accumulator: Accumulator, summary: dict, *,
              extent_mm: tuple[float, float, float, float] | None = None,
              field_radius_mm: float | None = None,
              field_half_size_mm: tuple[float, float] | None = None) -> dict[str, Path]:
    """Write irradiance.exr, preview.png and summary.json into out_dir. Returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ny, nx = accumulator.sum_image.shape
    if extent_mm is None:
        extent_mm = (-nx / 2, nx / 2, -ny / 2, ny / 2)
    paths = {"exr": out / "irradiance.exr", "png": out / "preview.png", "json": out / "summary.json"}
    write_exr(paths["exr"], accumulator.mean_image, accumulator.mean_parts, accumulator.part_names)
    title = f"{summary.get('method', '')} · {summary.get('passes', accumulator.n)} passes"
    b, shown = display_binning(accumulator.mean_image, accumulator.std_error_image)
    if b > 1:
        title += f" · shown as {b}×{b}-pixel means (EXR: full {nx}×{ny})"
    write_preview(paths["png"], shown, extent_mm, field_radius_mm, field_half_size_mm, title)
    write_summary(paths["json"], summary)
    return paths


__all__ = ["write_run", "display_binning", "write_exr", "read_exr", "write_preview", "write_summary", "channel_name"]
