"""`lensmount pst DESIGN --scene S --angles 0:30:1`: parses, calls lensmount.loop.pst, prints."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.errors import InputError
from lensmount.loop.pst import ANGLES_VALID, PstOptions, parse_angles, pst as sweep
from lensmount.loop.pst_report import EXCEEDS, NOT_JUDGED, judge, write_pst


@COMMANDS.register("pst", CommandLine)
def pst(
    design: Path = typer.Argument(..., help="Design folder (lens.toml or lens.zmx, mount.toml, scenes/)."),
    scene: Path = typer.Option(..., "--scene", help="Scene: a name from DESIGN/scenes/ or a scene file; its source is swept in angle, the rest kept."),
    angles: str = typer.Option("0:30:1", "--angles", help="Off-axis angles: " + ANGLES_VALID + "."),
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
    plane) against off-axis angle: pst.csv, pst.png (log scale, 1σ error bars, field edge and
    requirement marked) and report.html. Inside the field with `direct` on in the scene the direct image
    dominates; outside it, the stray light. The geometry is built once for all angles. With a
    [requirement] in the scene (PST limits by angle) the curve is judged: exit 1 when it exceeds the
    requirement at 99 % confidence at any angle (named), 0 otherwise."""
    try:
        options = PstOptions(Path(design), Path(scene), tuple(parse_angles(angles)), azimuth, method, passes,
                             photons_per_pass, seed, workers=workers, target_rel_error=target_rel_error)
        result = sweep(options, progress=lambda text: typer.echo(text, err=True))
        paths = write_pst(Path(out) if out else Path("out") / f"pst-{Path(scene).stem}", result)
    except InputError as error:
        fail(error)
    typer.echo(f"field edge {result.field_edge_deg:g}°")
    verdicts = judge(result)
    for p, v in zip(result.points, verdicts):
        err = (f" ± {p.std_error:.2g}" if p.std_error is not None else
               f" (< {p.upper_bound:.2g}, 95 %)" if p.upper_bound is not None else " (no error bar: see pst.csv)")
        verdict = f"  requirement: {v.state}" if v.state != NOT_JUDGED else ""
        typer.echo(f"{p.angle_deg:6g}°  PST {p.pst:.4g}{err}  {'in field' if p.in_field else ''}{verdict}")
    typer.echo("wrote " + ", ".join(str(p) for p in paths.values()))
    if result.requirement is not None:
        over = [v for v in verdicts if v.state == EXCEEDS]
        undecided = [f"{v.angle_deg:g}°" for v in verdicts if v.state == "undecided"]
        if undecided:
            typer.echo(f"requirement undecided at {', '.join(undecided)} (more passes decide it)", err=True)
        if over:
            typer.echo("the PST exceeds the requirement at 99 % confidence at "
                       + "; ".join(f"{v.angle_deg:g}° ({v.text})" for v in over), err=True)
            raise typer.Exit(code=1)
        typer.echo("the PST curve meets the requirement wherever it is decided")
