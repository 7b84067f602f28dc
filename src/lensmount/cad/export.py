"""STEP export: the assembly (part names and colours) and one file per part.

STEP headers carry a timestamp; we write a fixed one (STEP_TIMESTAMP) so that the
same part gives the same bytes on every run and "only the changed parts' STEP
files change" can be checked by comparing whole files. Files are written to a
temporary name in the target folder and renamed.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from lensmount.atomic import atomic_path

STEP_TIMESTAMP = "2000-01-01T00:00:00"

# display colours (r, g, b) per finish, then per kind; only for viewing the STEP
FINISH_COLOURS = {
    "black-anodised": (0.12, 0.12, 0.13),
    "absorber": (0.03, 0.03, 0.03),
    "ground-glass": (0.70, 0.82, 0.92),
    "mirror": (0.85, 0.85, 0.88),
}
KIND_COLOURS = {"lens": (0.62, 0.80, 0.95), "diaphragm": (0.25, 0.25, 0.28), "vane": (0.2, 0.2, 0.22)}


def colour_of(kind: str, finish: str) -> tuple[float, float, float]:
    if kind == "lens":
        return KIND_COLOURS["lens"]
    return FINISH_COLOURS.get(finish, KIND_COLOURS.get(kind, (0.5, 0.5, 0.5)))


def _atomic_step(shape, path: Path) -> None:
    from build123d import export_step  # lazy: build123d/OCP take seconds to load; only solid modelling needs them

    with atomic_path(path) as tmp:
        if not export_step(shape, str(tmp), timestamp=STEP_TIMESTAMP):
            raise OSError(f"STEP writer failed for {path}")


def _labelled(solid, name: str, kind: str, finish: str):
    from build123d import Color  # lazy: build123d/OCP take seconds to load; only solid modelling needs them

    s = solid.__class__(solid.wrapped)  # a fresh wrapper: labels/parents do not leak between exports
    s.label = name
    s.color = Color(*colour_of(kind, finish))
    return s


def write_part_step(solid, name: str, kind: str, finish: str, path: Path) -> None:
    """One part, named and coloured."""
    _atomic_step(_labelled(solid, name, kind, finish), path)


def write_assembly_step(parts, path: Path) -> None:
    """All parts as one assembly (each a named, coloured child). parts: [(solid, name, kind, finish)]."""
    from build123d import Compound  # lazy: build123d/OCP take seconds to load; only solid modelling needs them

    children = [_labelled(s, n, k, f) for s, n, k, f in parts]
    assembly = Compound(children=children)
    assembly.label = "assembly"
    _atomic_step(assembly, path)


__all__ = ["write_part_step", "write_assembly_step", "STEP_TIMESTAMP", "colour_of", "material_of", "bom_csv"]


GLASS_DENSITY_DEFAULT = 2.51  # g/cm³, N-BK7: the weight of a glass the BOM has no density for


def material_of(kind: str, template, prescription, spec) -> tuple[str, float, str]:
    """(material, density g/cm³, note) of a part: a lens's glass is the one after its front
    surface (prescription), a front-surface mirror's blank N-BK7 (a lens file names no blank
    material), every other part is `[bom] metal`."""
    if kind == "mirror":
        return ("N-BK7", spec.bom.glass_density_g_cm3.get("N-BK7", GLASS_DENSITY_DEFAULT),
                "mirror blank: the lens file names no blank material, N-BK7 assumed")
    if kind != "lens":
        return spec.bom.metal, spec.bom.metal_density_g_cm3, ""
    material = prescription.surfaces[template.front.index].material
    density = spec.bom.glass_density_g_cm3.get(material)
    if density is None:
        return material, GLASS_DENSITY_DEFAULT, "density of N-BK7 assumed: give [bom] glass_density_g_cm3"
    return material, density, ""


def bom_csv(rows, prescription, spec) -> str:
    """bom.csv text: part, kind, material, finish, volume (mm³), density (g/cm³), mass (g), note.

    rows: (name, kind, finish, volume_mm3, template) per part (materials: `material_of`).
    """
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["part", "kind", "material", "finish", "volume_mm3", "density_g_cm3", "mass_g", "note"])
    for name, kind, finish, volume, template in rows:
        material, density, note = material_of(kind, template, prescription, spec)
        w.writerow([name, kind, material, finish, f"{volume:.3f}", f"{density:g}", f"{volume * density * 1e-3:.3f}", note])
    return out.getvalue()
