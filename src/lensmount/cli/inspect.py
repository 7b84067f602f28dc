"""`lensmount inspect LENS [--json]`: the surfaces with their clear semi-diameters and the paraxial data.

Parses, calls lensmount.design / lensmount.optics, prints. No physics here.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional

import typer
from rich import box
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.options import GlassCatalogs
from lensmount.design.edges import clip_warnings
from lensmount.design.lens import import_notes, load_lens, load_lens_and_clips, save_lens_toml
from lensmount.errors import InputError
from lensmount.optics.folded import folded_axis
from lensmount.optics.glass import refractive_index
from lensmount.optics.paraxial import paraxial


def inspect_document(prescription, notes=None, clips=()) -> dict:
    """The `--json` document: paraxial data and one entry per surface (mm; radius null = plane).

    notes: for a .zmx, the import notes (kind imported/substituted/ignored, where, what).
    clips: the elements edged inside the beam (design.edges.EdgeClip): a row "clipped" per clip.
    """
    par = paraxial(prescription)
    wl = prescription.primary_wavelength_um
    z = prescription.vertex_z
    surfaces = []
    for i, s in enumerate(prescription.surfaces):
        surfaces.append({
            "number": i + 1,
            "radius_mm": None if math.isinf(s.radius) else s.radius,
            "thickness_mm": s.thickness,
            "material": s.material,
            "n_primary": float(refractive_index(s.material, wl)),
            "conic": s.conic,
            "aspheric": list(s.aspheric),
            "qtype": None if s.qtype is None else {
                "form": s.qtype.form, "norm_radius_mm": s.qtype.norm_radius,
                "coefficients_mm": list(s.qtype.coefficients),
                "vertex_radius_mm": None if s.vertex_curvature == 0.0 else 1.0 / s.vertex_curvature},
            "clear_semi_diameter_mm": s.clear_semi_diameter,
            "mechanical_semi_diameter_mm": s.mechanical_semi_diameter,
            "is_stop": s.is_stop,
            "coating": s.coating,
            "mirror": s.mirror,
            "z_mm": z[i],
        })
    doc = {
        "name": prescription.name,
        "afocal": par.afocal,
        "angular_magnification": par.angular_magnification,
        # an afocal system has no focal length, F/# or image at a finite distance (optics.paraxial)
        "efl_mm": None if par.afocal else par.efl,
        "bfl_mm": None if par.afocal else par.bfl,
        "f_number": None if par.afocal else par.f_number,
        "image_medium": prescription.image_medium,
        "image_index": par.image_index,
        "image_space_na": None if par.afocal else par.image_na,
        "image_space_focal_length_mm": None if par.afocal else par.image_space_focal_length,
        "epd_mm": par.epd,
        "entrance_pupil_z_mm": par.entrance_pupil_z,
        "exit_pupil_z_mm": par.exit_pupil_z,
        "exit_pupil_diameter_mm": par.exit_pupil_diameter,
        "stop_semi_diameter_mm": par.stop_semi_diameter,
        "paraxial_image_z_mm": None if par.afocal else par.image_z,
        "image_plane_z_mm": prescription.image_z,
        "stop_surface": prescription.stop_index + 1,
        "wavelengths_um": list(prescription.wavelengths_um),
        "primary_wavelength_um": wl,
        "field_angles_deg": list(prescription.field_angles_deg),
        "object_distance_mm": prescription.object_distance if prescription.finite_object else None,
        "object_heights_mm": list(prescription.object_heights_mm),
        "surfaces": surfaces,
    }
    clipped = {j: c.needed[k] for c in clips for k, j in enumerate(c.surfaces)}
    rows = [{"kind": n.kind, "where": n.where, "what": n.what + _recomputed(prescription, n, clipped)}
            for n in notes or ()]
    rows += [{"kind": "clipped", "where": f"SURF {c.surfaces[0] + 1}-{c.surfaces[1] + 1}", "what": what}
             for c, what in zip(clips, clip_warnings(clips))]
    if rows:
        doc["import_notes"] = rows
    if prescription.frames:
        doc.update(_placed(prescription))
    return doc


def _placed(prescription) -> dict:
    """For a lens off one axis: every surface's frame and the first-order data along the folded axis (the
    chief ray of the on-axis field); the coaxial paraxial data above are the unfolded lens's, so the focal
    ones are replaced."""
    axis = folded_axis(prescription)
    frames = []
    for i, f in enumerate(prescription.frames):
        tilt = f.tilts_deg()
        frames.append({"number": i + 1 if i < len(prescription.surfaces) else "image",
                       "origin_mm": list(f.origin), "axis": [float(v) for v in f.axis],
                       "tilt_x_deg": tilt[0], "tilt_y_deg": tilt[1], "tilt_z_deg": tilt[2]})
    def finite(v):   # a flat fold has no focal length: None, as for an afocal lens
        return v if math.isfinite(v) else None
    return {"frames": frames, "efl_mm": finite(axis.efl_y), "efl_x_mm": finite(axis.efl_x), "bfl_mm": None,
            "f_number": None,
            "image_space_na": None, "paraxial_image_z_mm": None,
            "chief_ray_image_mm": list(axis.image_point), "chief_ray_image_local_mm": list(axis.image_local)}


def _recomputed(prescription, note, clipped) -> str:
    """': 9.005 mm' for a note on a value the import left to real rays, as the loaded lens has it
    (the beam's own value beside the clipped one for a surface edged inside the beam), with the digits
    it takes to differ from the file's value, or said to be the file's value to 1 µm."""
    if note.surface is None or prescription.surfaces[note.surface].clear_semi_diameter is None:
        return ""
    got = prescription.surfaces[note.surface].clear_semi_diameter
    beam = clipped.get(note.surface, got)
    was = note.file_value_mm
    if was is not None and abs(beam - was) < 5e-4:
        text = f": {beam:.4g} mm, the file's value to 1 µm"
    else:
        digits = _digits_apart(beam, was)
        text = f": {beam:.{digits}g} mm" + (f" (the file's {was:.{digits}g} mm)" if digits > 4 else "")
    return text + (f", clipped to {got:.4g} mm" if note.surface in clipped else "")


def _digits_apart(value: float, other: float | None) -> int:
    """The significant digits (4 at least) at which `value` and `other` read differently."""
    digits = 4
    while other is not None and digits < 12 and f"{value:.{digits}g}" == f"{other:.{digits}g}":
        digits += 1
    return digits


def _print_tables(doc: dict) -> None:
    console = Console()
    if doc.get("import_notes"):
        imp = Table(title="what the import did with the file", title_justify="left", box=box.SIMPLE_HEAD)
        for col in ("", "where", "what"):
            imp.add_column(col, no_wrap=col != "what")
        for n in doc["import_notes"]:
            imp.add_row(n["kind"], n["where"], escape(n["what"]))   # "[checks]" is text, not markup
        console.print(imp)
    t = Table(title=f"{doc['name']} (mm; n at {doc['primary_wavelength_um']:g} µm; sd = semi-diameter)",
              title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("#", "radius", "thickness", "material", "n", "clear sd", "z vertex", "stop"):
        t.add_column(col, justify="left" if col in ("material", "stop") else "right", no_wrap=True, min_width=len(col))
    for s in doc["surfaces"]:
        radius = "inf" if s["radius_mm"] is None else f"{s['radius_mm']:.4f}"
        csd = "-" if s["clear_semi_diameter_mm"] is None else f"{s['clear_semi_diameter_mm']:.3f}"
        t.add_row(str(s["number"]), radius, f"{s['thickness_mm']:.4f}",
                  s["material"] + (" (mirror)" if s["mirror"] else ""), f"{s['n_primary']:.6f}",
                  csd, f"{s['z_mm']:.3f}", "STOP" if s["is_stop"] else "")
    console.print(t)
    if doc.get("frames"):
        _print_frames(console, doc)
    for s in doc["surfaces"]:
        if s["qtype"] is not None:
            q = s["qtype"]
            vertex = "inf" if q["vertex_radius_mm"] is None else f"{q['vertex_radius_mm']:.4f} mm"
            console.print(f"surface {s['number']}: Forbes Q-type ({'Qbfs' if q['form'] == 'qbfs' else 'Qcon'}) on the "
                          f"radius and conic {s['conic']:g} above, {len(q['coefficients_mm'])} terms on normalisation "
                          f"radius {q['norm_radius_mm']:g} mm; vertex (paraxial) radius {vertex}")
    title = ("paraxial data of the lens unfolded (z from surface 1 vertex), the focal lengths along the folded "
             "axis" if doc.get("frames") else "paraxial data (z from surface 1 vertex)")
    p = Table(title=title, title_justify="left", show_header=False)
    p.add_column("quantity")
    p.add_column("value", justify="right")
    if doc["afocal"]:
        focal = [("afocal", f"angular magnification {doc['angular_magnification']:.6g}x: no focal length, "
                  "F/# or image at a finite distance (init and simulate need a focusing lens)")]
    elif doc.get("frames"):
        focal = [(f"EFL {k} (folded axis)",
                  "none (no power)" if doc[key] is None else f"{doc[key]:.4f} mm")
                 for k, key in (("y", "efl_mm"), ("x", "efl_x_mm"))]
    else:
        focal = [("effective focal length", f"{doc['efl_mm']:.4f} mm"),
                 ("back focal length", f"{doc['bfl_mm']:.4f} mm"),
                 ("image-space F/#", f"{doc['f_number']:.4f}"),
                 ("image-space NA (paraxial, n' u')", f"{doc['image_space_na']:.4f}")]
        if doc["image_index"] != 1.0:   # an image formed in a medium: the detector in contact with it
            focal += [("image medium", f"{doc['image_medium']} (n' {doc['image_index']:.5f})"),
                      ("focal length in the image medium", f"{doc['image_space_focal_length_mm']:.4f} mm")]
    rows = [*focal,
            ("entrance pupil diameter", f"{doc['epd_mm']:.4f} mm"),
            ("entrance pupil z", f"{doc['entrance_pupil_z_mm']:.4f} mm"),
            ("exit pupil z", f"{doc['exit_pupil_z_mm']:.4f} mm"),
            ("exit pupil diameter", f"{doc['exit_pupil_diameter_mm']:.4f} mm"),
            *([("paraxial image z", f"{doc['paraxial_image_z_mm']:.4f} mm")]
              if doc["paraxial_image_z_mm"] is not None else []),
            ("image plane z (file)", f"{doc['image_plane_z_mm']:.4f} mm"),
            ("object", "at infinity" if doc["object_distance_mm"] is None
             else f"{doc['object_distance_mm']:g} mm in front of surface 1"),
            ("field angles", ", ".join(f"{a:g}°" for a in doc["field_angles_deg"])),
            *([("object heights", ", ".join(f"{h:g} mm" for h in doc["object_heights_mm"]))]
              if doc["object_heights_mm"] else []),
            ("wavelengths", ", ".join(f"{w:g}" for w in doc["wavelengths_um"]) + " µm")]
    for r in rows:
        p.add_row(*r)
    console.print(p)


def _print_frames(console, doc: dict) -> None:
    f = Table(title="frames: the surfaces do not share one axis (assembly frame, mm; tilts in the order-0 break "
              "convention)", title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("#", "origin (x, y, z)", "axis", "tilt x, y, z"):
        f.add_column(col, justify="right", no_wrap=True)
    for r in doc["frames"]:
        f.add_row(str(r["number"]), ", ".join(f"{v:.3f}" for v in r["origin_mm"]),
                  ", ".join(f"{v:.4f}" for v in r["axis"]),
                  ", ".join(f"{r[k] + 0.0:.3f}°" for k in ("tilt_x_deg", "tilt_y_deg", "tilt_z_deg")))
    console.print(f)
    x, y = doc["chief_ray_image_local_mm"]
    console.print(f"chief ray of the on-axis field on the image plane: ({x:.6f}, {y:.6f}) mm from its vertex")


@COMMANDS.register("inspect", CommandLine)
def inspect_command(
    lens: Path = typer.Argument(..., help="lens.toml or Zemax .zmx (or a design folder holding one)."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON document instead of tables."),
    margin: Optional[float] = typer.Option(None, "--margin", help="Margin (mm) added to automatic clear "
                                           "semi-diameters; default: the file's clear_aperture_margin_mm."),
    save_toml: Optional[Path] = typer.Option(None, "--save-toml", help="Also write the lens as lens.toml "
                                             "(e.g. to convert a .zmx); automatic semi-diameters stay automatic "
                                             "(a lens with vignetting factors: written out)."),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """Show a lens: what the import of a .zmx did (imported, substituted, ignored; where each glass
    was found), the surfaces with their clear semi-diameters, and the paraxial data (for an afocal
    system its angular magnification instead of a focal length)."""
    try:
        prescription, clips = load_lens_and_clips(lens, margin_mm=margin, afocal_ok=True, placed_ok=True)
        if save_toml is not None:
            raw = load_lens(lens, auto_clear_apertures=False, afocal_ok=True)
            # lens.toml has no vignetting factors: a vignetted lens keeps the semi-diameters they give
            save_lens_toml(prescription if raw.vignetting else raw, save_toml, margin_mm=margin or 0.0,
                           header=f"{raw.name}\nconverted by `lensmount inspect --save-toml` from {lens}")
        doc = inspect_document(prescription, import_notes(lens), clips)
    except InputError as error:
        fail(error)
        return
    if as_json:
        typer.echo(json.dumps(doc, indent=2))
    else:
        _print_tables(doc)
