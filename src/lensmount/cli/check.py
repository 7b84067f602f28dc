"""`lensmount check DESIGN [--exclusion-deg A]`: lit walls the detector sees, and the realised pupil.

Parses, builds (or restores) the geometry through lensmount.loop, calls
lensmount.loop.sightlines and lensmount.cad.pupil, prints and writes
check.json + check.png (check-aperture.* with --from aperture). Exit 1 when a lit wall is seen, 0 when none is, 2 on bad input.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from lensmount.atomic import write_text
from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.design.folder import load_design
from lensmount.cli.options import GlassCatalogs
from lensmount.errors import InputError
from lensmount.loop.regenerate import RegenerateOptions, regenerate as build
from lensmount.loop.sightlines import VIEWS, file_stem, lit_walls_seen, plot_report
from lensmount.mesh import TaggedMesh
from lensmount.optics.paraxial import paraxial


def exclusion_of(spec, prescription, override: float | None) -> float:
    """--exclusion-deg, else [hood] exclusion_deg, else the largest field angle + 5°."""
    if override is not None:
        if not 0.0 < override < 90.0:
            raise InputError(f"exclusion angle {override}° is outside (0°, 90°)", field="--exclusion-deg",
                             valid="an angle in degrees between 0 and 90")
        return float(override)
    return spec.exclusion_deg(prescription.max_field_deg)


def pupil_report(p, pupil) -> tuple[str, dict]:
    """The realised entrance pupil against the design's: one line and check.json's entry. At infinity
    as diameter and f-number; from a finite object as the object-space NA (the pupil's diameter too
    where it lies within reach). A pupil no axial ray passes names the part in the beam on the axis."""
    efl = paraxial(p).efl
    limited = sorted(set(pupil.limited_by))
    doc = {"realised_mm": pupil.diameter, "design_mm": pupil.design_diameter,
           "realised_f_number": abs(efl) / pupil.diameter if pupil.diameter > 0.0 else None,
           "design_f_number": abs(efl) / pupil.design_diameter, "limited_by": limited}
    if p.finite_object:
        doc |= {"realised_object_na": pupil.object_na, "design_object_na": pupil.design_object_na}
        within_reach = pupil.design_diameter < 1e6   # a telecentric object space has its pupil at infinity
        design = f"NA {pupil.design_object_na:.4f}" + (f" ({pupil.design_diameter:.3f} mm)" if within_reach else "")
        realised = f"NA {pupil.object_na:.4f}" + (f" ({pupil.diameter:.3f} mm)" if within_reach else "")
        rays = "from the axial object point"
    else:
        design = f"{pupil.design_diameter:.3f} mm (f/{abs(efl) / pupil.design_diameter:.2f})"
        realised = f"{pupil.diameter:.3f} mm (f/{abs(efl) / pupil.diameter:.2f})" if pupil.diameter > 0.0 else ""
        rays = "entering parallel to the axis"
    if pupil.diameter <= 0.0:
        return (f"entrance pupil: none realised: no ray {rays} reaches the image, each is stopped on the axis "
                f"by {', '.join(limited)} (a face of it stands in the beam); designed {design}"), doc
    return (f"entrance pupil: realised {realised}, designed {design}, {100 * pupil.relative_error:+.2f} %; "
            f"limited by {', '.join(limited)}"), doc


def run_check(design: Path, folder: Path, exclusion: float | None, echo=typer.echo, view: str = "detector") -> bool:
    """Check the geometry in `folder` (already regenerated from `design`) seen from `view`
    (lensmount.loop.sightlines.VIEWS); True when it passes."""
    # lazy: keeps lensmount --help from loading cad and matplotlib
    from lensmount.cad.pupil import realised_entrance_pupil

    d = load_design(design)
    p, spec = d.prescription, d.mount
    angle = exclusion_of(spec, p, exclusion)
    mesh = TaggedMesh.load(Path(folder) / "mesh.npz")
    size = (spec.housing.detector_width_mm, spec.housing.detector_height_mm)
    report = lit_walls_seen(p, mesh, size, angle, view)
    pupil = realised_entrance_pupil(p, mesh)
    said, pupil_doc = pupil_report(p, pupil)
    echo(said)
    for said in d.lens_warnings:   # an element edged inside the beam: the vignetting per field it costs
        echo(f"lens: {said}")
    who = "the entrance aperture" if view == "aperture" else "the detector"
    if report.passed:
        echo(f"no lit wall is seen: {report.lit_by} at {angle:g}° or beyond lights nothing {who} sees "
             f"({report.rays['backward']} backward, {report.rays['forward']} forward rays)")
    else:
        echo(f"{len(report.walls)} lit face(s) {who} sees with {report.lit_by} at {angle:g}° or beyond:")
        for w in report.walls:
            name = f"{w.part} face {w.face}" + (f" '{w.label}'" if w.label else "")  # a STEP face's name
            echo(f"  {name} ({w.kind}, {w.role}): {w.area_mm2:.1f} mm² at z {w.z_range[0]:.1f}"
                 f"…{w.z_range[1]:.1f} mm, r {w.r_range[0]:.1f}…{w.r_range[1]:.1f} mm, lit from "
                 f"{w.smallest_angle_deg:g}°")
    if report.edges:
        echo(f"  (and {len(report.edges)} lit vane edge(s), {sum(e.area_mm2 for e in report.edges):.1f} mm² in all: "
             "seen from the aperture by design, not counted)")
    out = Path(folder) / "check"
    out.mkdir(parents=True, exist_ok=True)
    png, json_path = out / f"{file_stem(view)}.png", out / f"{file_stem(view)}.json"
    plot_report(report, mesh, png)
    doc = {"exclusion_deg": angle, "seen_from": view, "passed": report.passed, "rays": report.rays,
           "lit_walls_seen": [w.__dict__ for w in report.walls],
           "lit_vane_edges_seen": [w.__dict__ for w in report.edges],
           "entrance_pupil": pupil_doc,
           "lens_vignetting": [{"surfaces": [c.surfaces[0] + 1, c.surfaces[1] + 1], "semi_diameter_mm": c.height,
                                "fields": list(c.fields), "field_unit": c.field_unit, "lost": list(c.lost)}
                               for c in d.lens_clips]}
    write_text(json_path, json.dumps(doc, indent=2) + "\n")
    echo(f"picture: {png}; details: {json_path}")
    return report.passed


@COMMANDS.register("check", CommandLine)
def check(
    design: Path = typer.Argument(..., help="design folder: lens.toml (or lens.zmx), mount.toml"),
    exclusion_deg: Optional[float] = typer.Option(
        None, "--exclusion-deg", help="smallest sun angle off the axis, degrees (default: mount.toml's "
        "hood.exclusion_deg, else the largest field angle + 5°)"),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="geometry folder (default DESIGN/build)"),
    seen_from: str = typer.Option("detector", "--from", help="whose view: 'detector' (through the lens) or "
                                  "'aperture' (the entrance aperture: lit hood walls the vanes must hide)"),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """Geometric stray-light check, no Monte Carlo: is any mount face both lit by the sun (at the
    exclusion angle or beyond, straight in or through the lens; a lens with its object at a finite
    distance: by its object plane, seen at those angles from the entrance pupil) and seen by the detector (over its
    area, through the exit pupil)? Lists each such face with its part, area and where it lies,
    draws check.png, and reports the entrance pupil the mount realises (real rays through the
    mesh) against the design's. With --from aperture, the walls seen from the entrance aperture
    instead (the classic vane criterion; lit vane edges are listed, not counted). Exit 1 when
    a lit wall is seen, 0 when none is."""
    try:
        if seen_from not in VIEWS:
            raise InputError(f"unknown view '{seen_from}'", field="--from", valid=" or ".join(VIEWS))
        folder = build(RegenerateOptions(design, out)).folder
        passed = run_check(design, folder, exclusion_deg, view=seen_from)
    except InputError as error:
        fail(error)
    raise typer.Exit(code=0 if passed else 1)
