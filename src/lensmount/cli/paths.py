"""`lensmount paths RESULT [--top 10] [--faces]`: where a run's stray light comes from; parses, calls, prints."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from lensmount.analysis.paths import face_measures, face_report, read_paths, signature_from_hex, top_paths
from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.atomic import NPZ_DAMAGE
from lensmount.errors import InputError
from lensmount.loop.simulate import PATHS
from lensmount.run.results import write_exr, write_preview


@COMMANDS.register("paths", CommandLine)
def paths(
    result: Path = typer.Argument(..., help="Output folder of `lensmount simulate` (holds summary.json and paths.npz)."),
    top: int = typer.Option(10, "--top", min=1, help="Paths (and faces) to print and to draw."),
    faces: bool = typer.Option(False, "--faces", help="Also the faces both seen by the detector and lit by the "
                                                      "source (bidirectional runs), ranked, with an image of each."),
) -> None:
    """The paths carrying most stray flux, each as its ordered scatter events (part, CAD face, role) with its
    fraction of the light entering the pupil and standard error; writes RESULT/paths/path-NN.png (the detector
    irradiance of that path alone) and paths.exr (a channel per path). With --faces: critical ∩ illuminated
    faces ranked by étendue × irradiance / π, then critical-but-unlit and lit-but-not-critical, with
    RESULT/paths/face-NN.png (the detector's view of the face, lit as measured, as a white Lambertian)."""
    source = Path(result) / PATHS
    try:
        if not source.is_file():
            raise InputError("no path data in this folder", file=str(source),
                             valid="the output folder of `lensmount simulate` run by this version")
        try:
            data = read_paths(source)
        except NPZ_DAMAGE as error:
            raise InputError(f"the path data is damaged and cannot be read ({type(error).__name__}: {error})", file=str(source),
                             valid="paths.npz written by `lensmount simulate` of this version") from None
    except InputError as error:
        fail(error)
    out = Path(result) / "paths"
    written = _paths(out, data, top)
    if faces:
        written += _faces(out, data, top)
    typer.echo("wrote " + ", ".join(str(p) for p in written))


def _paths(out: Path, data, top: int) -> list[Path]:
    sums, table_of_tags, _, aperture, extent = data
    report = top_paths(sums, table_of_tags, aperture, top)
    table = Table(title=f"stray paths by flux ({report['distinct_paths']} paths, {report['passes']} passes; total "
                        f"{_num(report['total_fraction'])} of the light entering the pupil)", title_justify="left")
    for column in ("rank", "events (in order)", "fraction", "± std error", "share"):
        table.add_column(column, justify="left" if column.startswith("events") else "right")
    for row in report["paths"]:
        table.add_row(str(row["rank"]), " → ".join(e["name"] for e in row["events"]), _num(row["fraction"]),
                      _num(row["std_error"]), "" if row["share"] is None else f"{100 * row['share']:.1f} %")
    other = report["other"]
    if other["paths"]:
        table.add_row("", f"{other['paths']} other paths", _num(other["fraction"]), _num(other["std_error"]), "")
    Console(width=max(Console().width, 120)).print(table)
    pictures = []
    for row in report["paths"]:
        image = sums.path_image(signature_from_hex(row["signature"]))
        if image is None:  # the run keeps images of its KEPT_IMAGES leading paths only
            typer.echo(f"path #{row['rank']}: no image (outside the leading paths whose images the run keeps)")
            continue
        pictures.append((f"path-{row['rank']:02d}", image,
                         f"path #{row['rank']}: " + " → ".join(e["name"] for e in row["events"])))
    return _write_images(out, "paths.exr", pictures, extent)


def _write_images(out: Path, exr_name: str, pictures, extent) -> list[Path]:
    """One PNG per (name, image, title) and one EXR holding them all as layers (their sum as RGB)."""
    written = []
    for name, image, title in pictures:
        written.append(out / f"{name}.png")
        write_preview(written[-1], image, extent, title=title)
    if pictures:
        images = np.stack([image for _, image, _ in pictures])
        written.append(out / exr_name)
        write_exr(written[-1], images.sum(axis=0), images, [name for name, _, _ in pictures])
    return written


def _faces(out: Path, data, top: int) -> list[Path]:
    sums, table_of_tags, areas, aperture, extent = data
    report = face_report(sums, table_of_tags, areas, aperture, top)
    console = Console(width=max(Console().width, 120))
    if not report["view_map"]:
        console.print("no view map in this run (forward): which faces the detector sees is unknown; "
                      "run with --method bidirectional")
        return []
    lists = (("critical_and_illuminated", "faces seen by the detector AND lit by the source, by G·E/π"),
             ("critical_unlit", "seen by the detector, not lit"), ("lit_not_critical", "lit, not seen by the detector"))
    for key, title in lists:
        table = Table(title=title, title_justify="left")
        for column in ("rank", "CAD face", "role", "finish", "area mm²", "E/E_sun", "G mm²·sr", "G·E/π mm²"):
            table.add_column(column, justify="right")
        for k, row in enumerate(report[key], 1):
            table.add_row(str(k), row["name"], row["role"], row["finish"], _num(row["area_mm2"]),
                          _num(row["irradiance"]), _num(row["etendue_mm2_sr"]), _num(row["product_mm2"]))
        console.print(table)
    m = face_measures(sums, areas)
    per_block = sums.pixels_per_block()
    pictures = []
    for k, row in enumerate(report["critical_and_illuminated"], 1):
        t = row["tag"]
        image = sums.seen_images[t] / max(sums.seen_passes, 1) / per_block * m["irradiance"][t] / math.pi
        pictures.append((f"face-{k:02d}", image,
                         f"face #{k}: {row['name']} ({row['role']}), as a white Lambertian"))
    return _write_images(out, "faces.exr", pictures, extent)


def _num(value) -> str:
    return "—" if value is None else f"{value:.3g}"
