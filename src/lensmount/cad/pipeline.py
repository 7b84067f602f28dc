"""`regenerate`: design folder → assembly.step, parts/NAME.step (+ NAME.svg, NAME.dxf drawings),
mesh.npz, bom.csv, manifest.json.

manifest.json:

    {"input_hash": "<sha256>", "lensmount_version": "0.1.0",
     "assembly": "assembly.step", "mesh": "mesh.npz",
     "tessellation": {"linear_tolerance_mm": .., "angular_tolerance_deg": ..},
     "parts": [{"name", "kind", "finish", "step", "volume_mm3", "triangles", "hash",
                "svg", "dxf", "drawing_hash", "faces"}, ...],   # faces: NAME.faces.png of a STEP part, else ""
     "notes": [...]}

A part's STEP file is rewritten only when its own hash (its template parameters,
finish, user template) changed, its drawings only when that hash, `[drawing]` or its
material changed, so changing one parameter changes only the
affected parts' files (and assembly.step, mesh.npz, manifest.json). A run whose
input hash is cached returns from the cache (lensmount.cad.cache).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

import lensmount
from lensmount.atomic import atomic_dir, checksum_holds, with_checksum, write_text
from lensmount.cad import cache
from lensmount.cad.assembly import build_assembly, tessellate
from lensmount.cad.drawing import dimensions, title_block, write_drawing
from lensmount.cad.export import bom_csv, material_of, write_assembly_step, write_part_step
from lensmount.cad.step_parts import StepSource, face_picture
from lensmount.design.folder import load_design
from lensmount.errors import InputError
from lensmount.validation import located

MANIFEST = "manifest.json"
BOM = "bom.csv"
ASSEMBLY = "assembly.step"
MESH = "mesh.npz"
STEPS = ("layout", "checks", "solids", "tessellation", "export")


@dataclass
class PartEntry:
    name: str
    kind: str
    finish: str
    step: str
    volume_mm3: float
    triangles: int
    hash: str
    svg: str
    dxf: str
    drawing_hash: str
    faces: str = ""  # parts/NAME.faces.png of a STEP part: its face indices drawn

    def files(self) -> list[str]:
        return [self.step, self.svg, self.dxf] + ([self.faces] if self.faces else [])


@dataclass
class Manifest:
    input_hash: str
    parts: list[PartEntry]
    lensmount_version: str = lensmount.__version__
    assembly: str = ASSEMBLY
    mesh: str = MESH
    tessellation: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # what the user should know before a run (printed as such)
    checksums: dict[str, str] = field(default_factory=dict)  # sha256 of every output file but manifest.json
    cached: bool = False  # not written: True when this run came from the cache

    def to_json(self) -> str:
        d = asdict(self)
        d.pop("cached")
        return json.dumps(with_checksum(d), indent=2)

    @classmethod
    def from_json(cls, text: str, cached: bool = False) -> "Manifest":
        """The manifest; ValueError when its checksum disagrees (damaged: rebuilt, never trusted)."""
        d = json.loads(text)
        if not checksum_holds(d):
            raise ValueError("manifest.json does not match its checksum")
        d["parts"] = [PartEntry(**p) for p in d["parts"]]
        return cls(**d, cached=cached)

    def files(self) -> list[str]:
        """Every file the build wrote but manifest.json: what `checksums` covers, what the cache keeps
        and what a folder must hold to be served from it."""
        return [self.assembly, self.mesh, BOM] + [f for p in self.parts for f in p.files()]

    def part(self, name: str) -> PartEntry:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(name)




def _previous(out: Path) -> Manifest | None:
    """The folder's manifest, when there is one and its files are whole (their checksums agree):
    a damaged output or cache entry is rebuilt, never trusted."""
    try:
        manifest = Manifest.from_json((out / MANIFEST).read_text())
    except (OSError, ValueError, KeyError, TypeError):
        return None
    files = manifest.files()
    if set(files) != set(manifest.checksums) or any(_sha256(out / f) != manifest.checksums[f] for f in files):
        return None
    return manifest


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def regenerate(design_dir, out_dir=None, progress=None, use_cache: bool = True,
               tessellation: dict | None = None) -> Manifest:
    """Regenerate a design's CAD outputs.

    Args:
        design_dir: the design folder (lens file, mount.toml, scenes/).
        out_dir: output folder; defaults to DESIGN/build.
        progress: optional callable progress(step, done, total), step one of STEPS.
        use_cache: return from the content-addressed cache when the inputs are unchanged.
        tessellation: overrides of mount.toml's [tessellation] (`linear_tolerance_mm`,
            `angular_tolerance_deg`); they become part of the cache key.
    Returns:
        The Manifest (also written as OUT/manifest.json); `.cached` tells whether the
        CAD kernel ran.
    """
    design = load_design(design_dir)
    out = Path(out_dir) if out_dir is not None else design.root / "build"
    key = design.input_hash
    spec = design.mount
    if tessellation:
        try:
            tess = spec.tessellation.model_validate({**spec.tessellation.model_dump(), **tessellation})
        except ValueError as exc:
            raise InputError(f"bad tessellation option: {exc.errors()[0]['msg']}", field="tessellation",
                             valid="linear tolerance > 0 mm, angular tolerance in (0, 45] degrees") from None
        spec = spec.model_copy(update={"tessellation": tess})
        key = hashlib.sha256((key + json.dumps(tess.model_dump(), sort_keys=True)).encode()).hexdigest()
    prev = _previous(out)
    if use_cache:
        if prev is not None and prev.input_hash == key:
            prev.cached = True
            return prev
        entry = cache.cache_dir(out, key)
        m = _previous(entry)
        if m is not None:
            with atomic_dir(out) as new:
                cache.restore(entry, new)
            m.cached = True
            return m
        if entry.exists():  # damaged or incomplete: built again below
            shutil.rmtree(entry)

    layout, parts, mesh, triangles = _build(design, spec, progress)

    # The new outputs are made beside OUT and swapped in whole: a refused, failed or stopped
    # regenerate leaves OUT as it was (or absent), never empty or half written.
    with atomic_dir(out) as new:
        prev_hash = {p.name: p.hash for p in prev.parts} if prev else {}
        prev_drawing = {p.name: p.drawing_hash for p in prev.parts} if prev else {}
        for p in prev.parts if prev else []:  # a part's files are kept while it is unchanged (hard links)
            if p.name in triangles:
                for rel in p.files():
                    cache.place(out / rel, new / rel)
        entries = []
        for k, bp in enumerate(parts):
            rel = f"parts/{bp.name}.step"
            if prev_hash.get(bp.name) != bp.hash or not (new / rel).is_file():
                write_part_step(bp.solid, bp.name, bp.plan.kind, bp.plan.finish, new / rel)
            svg, dxf, d_hash = _drawings(new, bp, layout, spec, prev_drawing.get(bp.name))
            picture = ""
            if isinstance(bp.plan.template, StepSource):  # the face numbers a rule names
                picture = f"parts/{bp.name}.faces.png"
                face_picture(mesh.select(np.array([t.part == bp.name for t in mesh.tag_table])[mesh.tags]),
                             f"{bp.name} from {bp.user_template.name}: STEP face indices", new / picture)
            entries.append(PartEntry(bp.name, bp.plan.kind, bp.plan.finish, rel, float(bp.solid.volume),
                                     triangles[bp.name], bp.hash, svg, dxf, d_hash, picture))
            if progress:
                progress("export", k + 1, len(parts) + 2)
        write_assembly_step([(bp.solid, bp.name, bp.plan.kind, bp.plan.finish) for bp in parts], new / ASSEMBLY)
        mesh.save(new / MESH)
        if progress:
            progress("export", len(parts) + 2, len(parts) + 2)
        write_text(new / BOM, bom_csv([(bp.name, bp.plan.kind, bp.plan.finish, float(bp.solid.volume),
                                        bp.plan.template) for bp in parts], layout.prescription, spec))
        manifest = Manifest(key, entries, tessellation=spec.tessellation.model_dump(),
                            notes=[f"lens: {w}" for w in design.lens_warnings] + list(layout.notes),
                            warnings=list(layout.warnings))
        manifest.checksums = {f: _sha256(new / f) for f in manifest.files()}
        write_text(new / MANIFEST, manifest.to_json())
    cache.store(out, key, manifest.files() + [MANIFEST])
    return manifest


def _build(design, spec, progress=None):
    """Layout, solids and the tagged mesh of a loaded design: (layout, parts, mesh, triangles per part).
    InputError with the mount.toml line of the field at fault."""
    try:
        layout, parts = build_assembly(design.prescription, spec, design.template_paths, progress, design.step_paths)
        mesh, triangles = tessellate(parts, spec, layout, progress)  # a STEP part's beam check stops it here
    except InputError as exc:
        raise located(exc, str(design.mount_path), design.mount.source_text) from None  # with the field's line
    return layout, parts, mesh, triangles


def warm(design_dir) -> None:
    """Build the design's parts as `regenerate` would and write nothing: the CAD kernel loaded, the lens's
    beam envelope and every part's tessellation kept in this process (`cad.assembly`). A long-lived process
    (`lensmount watch`) whose geometry came from the disk cache then pays, at an edit, only for the parts
    the edit changed, not for the kernel's import and all 17 parts (13.8 CPU s on the reference design, 2.2
    warm: CHANGELOG.md, "Around the passes")."""
    design = load_design(design_dir)
    _build(design, design.mount)


def _drawings(out: Path, bp, layout, spec, previous_hash: str | None) -> tuple[str, str, str]:
    """parts/NAME.svg and .dxf (lensmount.cad.drawing), rewritten only when what they show changed.

    A user-template part is drawn as its section with no template dimensions: the template's
    numbers describe the built-in part it replaces, not the user's solid.
    """
    material = material_of(bp.plan.kind, bp.plan.template, layout.prescription, spec)[0]
    payload = json.dumps([bp.hash, material, spec.drawing.model_dump()], sort_keys=True)
    d_hash = hashlib.sha256(payload.encode()).hexdigest()
    svg, dxf = f"parts/{bp.name}.svg", f"parts/{bp.name}.dxf"
    if d_hash != previous_hash or not (out / svg).is_file() or not (out / dxf).is_file():
        dims = [] if bp.user_template is not None else dimensions(bp.plan, spec.drawing)
        title = title_block(bp.name, bp.plan.kind, material, bp.plan.finish, spec.drawing)
        if bp.user_template is not None:
            title.append(f"from {bp.user_template.name}: section only, dimension from the user's file")
        write_drawing(bp.solid, dims, title, out / svg, out / dxf)
    return svg, dxf, d_hash


__all__ = ["regenerate", "warm", "Manifest", "PartEntry", "STEPS"]
