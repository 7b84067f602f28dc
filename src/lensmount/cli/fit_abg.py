"""`lensmount fit-abg DATA`: fit ABg to a measured BRDF (Zemax tabular .bsdf or CSV); parses, calls, prints."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.design.brdf_data import read_brdf
from lensmount.errors import InputError
from lensmount.run.results import save_figure


POOR_FIT_DECADES = 0.2  # rms error of log10 BRDF above which the fit is called poor (a factor 1.6)


@COMMANDS.register("fit-abg", CommandLine)
def fit_abg_command(
    data: Path = typer.Argument(..., help="Measured BRDF: a Zemax tabular .bsdf file, or a .csv with columns "
                                          "incidence_deg,scatter_deg,brdf (in-plane, scatter angle from the normal)."),
    name: str = typer.Option("measured", "--name", help="Finish name in the printed \\[finishes] lines."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write a PNG of the points, the table and the fit."),
) -> None:
    """Fit A/(B + |β − β0|^g) to the measurement (least squares in log BRDF) and check both the fit and the
    measured table for energy (TIS ≤ 1). Prints the fit's rms error in decades of BRDF (a warning above
    0.2, a factor 1.6: then use the measured table) and the finish lines to paste into \\[finishes]."""
    from lensmount.physics.bsdf import make_bsdf  # lazy: keeps lensmount --help from loading the BSDF models (~0.2 s)
    from lensmount.physics.bsdf.tabulated import fit_abg, measured_profile

    try:
        rho, f = read_brdf(data)
        a, b, g, rms = fit_abg(rho, f)
        table = make_bsdf("tabulated", **dict(zip(("rho", "brdf"), measured_profile(rho, f))))
        fitted = make_bsdf("abg", A=a, B=b, g=g)
    except InputError as error:
        fail(error.located(str(data)))
    typer.echo(f"{len(rho)} points from {data}")
    typer.echo(f"ABg fit: A = {a:.4g} 1/sr, B = {b:.4g}, g = {g:.4g}  (rms error {rms:.3f} decades of BRDF, "
               f"a factor {10 ** rms:.2f})")
    if rms > POOR_FIT_DECADES:
        typer.echo(f"warning: a poor fit: the ABg curve misses the measurement by {rms:.2f} decades rms (a factor "
                   f"{10 ** rms:.1f}; above {POOR_FIT_DECADES} decades ABg does not describe this surface): use the "
                   f"measured table ('{name}' below), not '{name}-abg'", err=True)
    typer.echo(f"TIS at normal incidence: fit {fitted.tis:.4g}, measured table {table.tis:.4g}")
    typer.echo("\n[finishes]")
    typer.echo(f'{name}-abg = {{ model = "abg", A = {a:.6g}, B = {b:.6g}, g = {g:.6g} }}')
    typer.echo(f'{name} = {{ model = "tabulated", file = "{data.name}" }}')
    if plot is not None:
        _plot(plot, rho, f, table, (a, b, g))
        typer.echo(f"wrote {plot}")


def _plot(path: Path, rho, f, table, abg) -> None:
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b, g = abg
    x = np.geomspace(max(float(rho.min()), 1e-6), 2.0, 300)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.loglog(rho, np.maximum(f, 1e-12), ".", ms=3, alpha=0.5, label="measured points")
    ax.loglog(table.rho, np.maximum(table.brdf, 1e-12), "s-", ms=3, label=f"table (TIS {table.tis:.3g})")
    ax.loglog(x, a / (b + x ** g), "-", label=f"ABg fit A={a:.3g} B={b:.3g} g={g:.3g}")
    ax.set_xlabel("|β − β0| (direction cosines)")
    ax.set_ylabel("BRDF (1/sr)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
