"""A design folder: lens file + mount.toml + scenes/, loaded and content-hashed.

    DESIGN/
      lens.toml | lens.zmx     the prescription (exactly one)
      mount.toml               the mount (docs/mount-toml.md)
      finishes.toml            optional: finishes, coatings and which faces get which (design.finishes),
                               shared by every scene
      scenes/*.toml            the test conditions: source, detector, effects, run (names = file stems)
      templates/*.py           optional user templates named in mount.toml
      *.step                   optional parts from STEP files named in mount.toml ([parts.NAME])

`input_hash` is the SHA-256 of what the CAD depends on: the lens file's bytes, the
mount file's bytes, every user template's and STEP part file's bytes and the lensmount version
(so a new export from the mechanical CAD is a new revision). It keys the regenerate cache
(lensmount.cad.cache); finishes.toml is not in it (a paint change rebuilds no geometry), but is
in a run's input hash (loop.simulate).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import lensmount
from lensmount.design.edges import EdgeClip, clip_gap, clip_warnings
from lensmount.design.finishes import FINISHES_NAME, Finishes, load_finishes
from lensmount.design.lens import LENS_NAMES, find_lens, load_lens_and_clips
from lensmount.design.mount import MountSpec, load_mount
from lensmount.errors import InputError
from lensmount.optics.prescription import Prescription
from lensmount.validation import line_of_key

MOUNT_NAME = "mount.toml"


@dataclass(frozen=True)
class Design:
    """A loaded design folder.

    Args:
        root: the folder.
        lens_path: the lens file.
        prescription: the lens, clear semi-diameters completed (automatic where the file gives none).
        mount_path: mount.toml.
        mount: the validated mount.
        scenes: scene name → path.
        template_paths: part kind → user template file.
        step_paths: part name → STEP file of a `[parts.NAME]` entry.
        input_hash: content hash of the CAD inputs (hex).
        finishes: the surface treatment (finishes.toml; the built-in one without the file).
        lens_clips: those elements edged inside the beam (design.edges.EdgeClip: size, vignetting per field).
        lens_warnings: what the import changed that a result depends on (design.edges: elements
            edged inside the beam, and what that vignettes); regenerate and simulate report them.
    """

    root: Path
    lens_path: Path
    prescription: Prescription
    mount_path: Path
    mount: MountSpec
    scenes: dict[str, Path]
    template_paths: dict[str, Path]
    input_hash: str
    lens_warnings: tuple[str, ...] = ()
    step_paths: dict[str, Path] = field(default_factory=dict)  # [parts.NAME] → its STEP file
    finishes: Finishes = Finishes()
    lens_clips: tuple[EdgeClip, ...] = ()   # the elements edged inside the beam (lens_warnings says them)

    @property
    def finishes_path(self) -> Path | None:
        """finishes.toml, None when the design has none."""
        path = self.root / FINISHES_NAME
        return path if path.is_file() else None


def content_hash(lens_path: Path, mount_path: Path, templates: dict[str, Path],
                 steps: dict[str, Path] | None = None, glass_catalogs=()) -> str:
    """glass_catalogs: the .agf files the lens's glasses were looked up in (their indices move the
    automatic semi-diameters, and so the mount)."""
    h = hashlib.sha256()
    h.update(f"lensmount {lensmount.__version__}\n".encode())
    for label, path in [("lens", lens_path), ("mount", mount_path)] + sorted(
            (f"template:{k}", v) for k, v in templates.items()) + sorted(
            (f"step:{k}", v) for k, v in (steps or {}).items()) + [
            (f"glass catalogue {k}", Path(c)) for k, c in enumerate(glass_catalogs)]:
        data = path.read_bytes()
        h.update(f"{label} {len(data)}\n".encode())
        h.update(data)
    return h.hexdigest()


def _check_element_numbers(mount: MountSpec, prescription: Prescription) -> None:
    """Element numbers in mount.toml must exist in the lens (an unknown one would be ignored)."""
    n = sum(len(g) - 1 for g in prescription.lens_groups())
    for number in mount.lens_edge.semi_diameter_mm:
        if not 1 <= number <= n:
            field = f"lens_edge.semi_diameter_mm.{number}"
            raise InputError(f"the lens has no element {number}", file=mount.source_file, field=field,
                             line=line_of_key(mount.source_text, "lens_edge.semi_diameter_mm"),
                             valid=f"element numbers 1 to {n} (from the object side)")


def load_design(directory: str | Path) -> Design:
    """Load and validate a design folder (InputError on anything a user must fix)."""
    root = Path(directory)
    if not root.is_dir():
        raise InputError("design folder not found", file=str(root),
                         valid="a folder with lens.toml (or lens.zmx) and mount.toml; "
                               "`lensmount init DIR --example double-gauss-360` makes one")
    lens_path = find_lens(root)
    mount_path = root / MOUNT_NAME
    if not mount_path.is_file():
        raise InputError("no mount.toml in the design folder", file=str(root),
                         valid="a mount.toml (docs/mount-toml.md)")
    mount = load_mount(mount_path)
    templates = {}
    for kind, rel in mount.templates.items():
        path = (root / rel)
        if not path.is_file():
            raise InputError(f"user template file {rel!r} not found", file=str(mount_path),
                             field=f"templates.{kind}", valid="a .py file path relative to the design folder")
        templates[kind] = path
    steps = {}
    for name, entry in mount.parts.items():
        path = root / entry.step
        if not path.is_file():
            field_ = f"parts.{name}.step"
            raise InputError(f"STEP file {entry.step!r} not found", file=str(mount_path), field=field_,
                             line=line_of_key(mount.source_text, field_),
                             valid="a .step/.stp file path relative to the design folder")
        steps[name] = path
    # the mount may let the glass size an element whose faces cross inside the beam (its own least edge)
    edged = {"clip_edge_mm": clip_gap(mount), "max_clip_vignetting": None, "clip_thin": True} \
        if mount.lens_edge.allow_vignetting else {}
    prescription, clips = load_lens_and_clips(lens_path, **edged)
    _check_element_numbers(mount, prescription)
    scenes_dir = root / "scenes"
    scenes = {p.stem: p for p in sorted(scenes_dir.glob("*.toml"))} if scenes_dir.is_dir() else {}
    return Design(root, lens_path, prescription, mount_path, mount, scenes, templates,
                  content_hash(lens_path, mount_path, templates, steps, prescription.glass_catalogs),
                  tuple(clip_warnings(clips)), steps,
                  load_finishes(root), clips)


__all__ = ["Design", "load_design", "content_hash", "find_lens", "LENS_NAMES"]
