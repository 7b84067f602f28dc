"""`lensmount pst DESIGN --scene S --angles 0:30:1`: parses, calls lensmount.loop.pst, prints."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.errors import InputError
from lensmount.loop.pst import PstOptions, parse_angles, pst as sweep, write_pst


@COMMANDS.register("pst", CommandLine)
def pst(
    design: Path = typer.Argument(..., help="Design folder (lens.toml or lens.zmx, mount.toml, scenes/)."),
    scene: Path = typer.Option(..., "--scene", help="Scene file; its source is swept in angle, the rest kept."),
    angles: str = typer.Option("0:30:1", "--angles",
                               help="Off-axis angles in degrees: start:stop:step (stop included) or a list 0,7,20."),
    azimuth: Optional[float] = typer.Option(None, "--azimuth",
                                            help="Direction of the tilt in degrees (default: the scene's)."),
    method: str = typer.Option("bidirectional", "--method", help="bidirectional | forward | a plug-in integrator."),
    passes: Optional[int] = typer.Option(None, "--passes", help="At most this many passes per angle (default: the "
                                                                "scene's run table; alone: exactly this many)."),
    target_rel_error: Optional[float] = typer.Option(None, "--target-rel-error",
                                                     help="Each angle stops at this relative error of its PST "
                                                          "(std + bias bound; default: the scene's run table)."),
    photons_per_pass: Optional[int] = typer.Option(None, "--photons-per-pass",
                                                   help="Photons per pass (default: the scene's run table)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed, >= 0 (default: the scene's run table seed)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Output folder (default out/pst-<scene name>)."),
    workers: int = typer.Option(0, "--workers", help="Worker processes for each angle's passes (0 = one per core)."),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """Point source transmittance (detector irradiance over the irradiance on the entrance
    plane) against off-axis angle: pst.csv, pst.png (log scale, error bars, field edge
    marked) and report.html. Inside the field with `direct` on in the scene the direct image
    dominates; outside it, the stray light. The geometry is built once for all angles."""
    try:
        options = PstOptions(Path(design), Path(scene), tuple(parse_angles(angles)), azimuth, method, passes,
                             photons_per_pass, seed, workers=workers, target_rel_error=target_rel_error)
        result = sweep(options, progress=lambda text: typer.echo(text, err=True))
        paths = write_pst(Path(out) if out else Path("out") / f"pst-{Path(scene).stem}", result)
    except InputError as error:
        fail(error)
    typer.echo(f"field edge {result.field_edge_deg:g}°")
    for p in result.points:
        err = "" if p.std_error is None else f" ± {p.std_error:.2g}"
        typer.echo(f"{p.angle_deg:6g}°  PST {p.pst:.4g}{err}  {'in field' if p.in_field else ''}")
    typer.echo("wrote " + ", ".join(str(p) for p in paths.values()))
