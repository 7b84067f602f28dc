"""`lensmount ghosts DESIGN --scene S`: every two-reflection ghost, ranked; parses, calls, prints."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from lensmount.atomic import write_text
from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.errors import InputError
from lensmount.loop.ghosts import ghost_report
from lensmount.loop.prepare import prepare
from lensmount.run.results import write_exr, write_preview
from lensmount.trace.tracer import Tracer


@COMMANDS.register("ghosts", CommandLine)
def ghosts(
    design: Path = typer.Argument(..., help="Design folder."),
    scene: Path = typer.Option(..., "--scene", help="Scene file: its source, detector, wavelengths and coatings."),
    out: Optional[Path] = typer.Option(None, "--out", help="Output folder (default out/<scene name>-ghosts)."),
    top: int = typer.Option(10, "--top", min=1, help="Pairs to print and to draw."),
    rays_across: int = typer.Option(151, "--rays-across", min=11, help="Ray lattice points across the first clear "
                                                                     "aperture (per wavelength)."),
    order: Optional[int] = typer.Option(None, "--order", min=2, max=3, help="2: two-reflection ghosts; 3: four-"
                                        "reflection ones too (default: the scene's [effects] ghosts order, else 2)."),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """Trace every two-reflection ghost path (with order 3 the four-reflection ones too) deterministically
    (real rays, real Fresnel or coating reflectance per wavelength) and rank them by peak irradiance on the
    detector: the ghost that makes a visible spot first. Writes ghosts.json, ghosts.csv, ghosts.exr (a channel per pair) and one PNG per pair."""
    try:
        prepared = prepare(design, scene, stage=lambda text: typer.echo(text, err=True))
        effects = prepared.scene.effects
        wanted = order if order is not None else (effects.ghost_order if effects.ghosts else 2)
        report = ghost_report(prepared.scene, Tracer(prepared.scene), rays_across, wanted)
    except InputError as error:
        fail(error)
    out = Path(out) if out is not None else Path("out") / f"{Path(scene).stem}-ghosts"
    paths = _write(out, report, prepared.scene.detector, top)
    _print(report, top)
    typer.echo("wrote " + ", ".join(str(p) for p in paths))


def _write(out: Path, report, det, top: int) -> list[Path]:
    rows = ["rank,surfaces,first,second,fraction,share,peak_irradiance,focus_from_detector_mm,centroid_x_mm,"
            "centroid_y_mm,radius90_mm"]
    for k, g in enumerate(report.pairs, 1):
        focus = "" if g.focus_from_detector_mm is None else f"{g.focus_from_detector_mm:.6g}"
        route = " ".join(str(x) for x in g.surfaces)
        rows.append(f"{k},{route},{g.first},{g.second},{g.fraction:.6g},{g.share:.6g},{g.peak_irradiance:.6g},{focus},"
                    f"{g.centroid_mm[0]:.6g},{g.centroid_mm[1]:.6g},{g.radius90_mm:.6g}")
    paths = [out / "ghosts.json", out / "ghosts.csv"]
    write_text(paths[0], json.dumps(report.to_dict(), indent=2) + "\n")
    write_text(paths[1], "\n".join(rows) + "\n")
    extent = (-det.width / 2, det.width / 2, -det.height / 2, det.height / 2)
    if report.pairs:
        images = np.stack([g.image for g in report.pairs])
        paths.append(out / "ghosts.exr")
        write_exr(paths[-1], images.sum(axis=0), images, [f"ghost-{g.slug}" for g in report.pairs])
        for k, g in enumerate(report.pairs[:top], 1):
            paths.append(out / f"ghost-{k:02d}-{g.slug}.png")
            write_preview(paths[-1], g.image, extent, title=f"ghost #{k}: surfaces {g.label}")
    return paths


def _print(report, top: int) -> None:
    console = Console()
    if not report.pairs:
        console.print("no ghost reaches the detector" + (f" ({len(report.skipped)} pairs have no reflectance)"
                                                         if report.skipped else ""))
        return
    table = Table(title=f"ghosts (order {report.order}) by peak irradiance ({report.rays_per_pair:,} rays per route; "
                        f"total {report.total_fraction:.3g} of the light entering the pupil)", title_justify="left")
    for column in ("rank", "surfaces", "peak E/E_sun", "fraction", "share", "focus from detector", "r90 (mm)"):
        table.add_column(column, justify="right")
    for k, g in enumerate(report.pairs[:top], 1):
        focus = "collimated" if g.focus_from_detector_mm is None else f"{g.focus_from_detector_mm:+.2f} mm"
        table.add_row(str(k), g.label, f"{g.peak_irradiance:.3g}", f"{g.fraction:.3g}",
                      f"{100 * g.share:.1f} %", focus, f"{g.radius90_mm:.2f}")
    console.print(table)
