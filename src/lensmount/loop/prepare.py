"""The first half of every loop command: design folder + scene file → the Scene the tracer sees.

`simulate`, `pst` and `ghosts` all start here: read and validate the design and the scene,
take the mount geometry from regenerate's folder (rebuilt only when the design changed),
and build the Scene (pure data).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from lensmount.design.finishes import check_mount_finishes
from lensmount.errors import InputError
from lensmount.design.folder import Design, load_design
from lensmount.design.mount import check_finish_parts
from lensmount.design.scene import SceneSpec, fit_detector_to_housing, load_scene
from lensmount.loop.regenerate import RegenerateOptions, RegenerateResult, regenerate
from lensmount.mesh import TaggedMesh
from lensmount.scene.scene import Scene


@dataclass
class Prepared:
    design: Design
    spec: SceneSpec
    built: RegenerateResult
    scene: Scene


def scene_file(design_dir: Path, scene: str | Path) -> Path:
    """The scene `scene` names: a file, or the name of one in DESIGN/scenes/ ("case2-lambertian");
    InputError listing the design's scenes when it is neither."""
    given = Path(scene)
    if given.is_file():
        return given
    candidate = Path(design_dir) / "scenes" / f"{given.name.removesuffix('.toml')}.toml"
    if candidate.is_file():
        return candidate
    folder = Path(design_dir) / "scenes"
    names = sorted(q.stem for q in folder.glob("*.toml")) if folder.is_dir() else []
    raise InputError(f"scene {str(scene)!r} not found: neither a file nor a scene of the design", file=str(scene),
                     field="--scene", valid="a scene file, or the name of one in " + str(folder) + ": "
                     + (", ".join(names) or "(it holds none)"))


def read_inputs(design_dir: Path, scene_path: Path, stage: Callable[[str], None] | None = None):
    """The validated design folder and scene file, (Design, SceneSpec); nothing built yet, so a
    caller can refuse bad options and unwritable outputs before the slow part."""
    (stage or (lambda text: None))("reading the design and the scene")
    design = load_design(design_dir)
    spec = load_scene(Path(scene_path), design.finishes)
    check_mount_finishes(design.finishes, design.mount)
    return design, fit_detector_to_housing(spec, design.mount)


def build(design, spec, geometry: Path | None = None, stage: Callable[[str], None] | None = None,
          build_step: Callable[[str, int, int], None] | None = None) -> Prepared:
    """Regenerate (cached) into `geometry` (default DESIGN/build) and build the Scene."""
    # lazy: keeps lensmount --help from loading scene.build and the BSDF models
    from lensmount.scene.build import build_scene

    say = stage or (lambda text: None)
    folder = Path(geometry) if geometry is not None else design.root / "build"
    say(f"mount geometry: {folder} (rebuilt only if the design changed)")
    built = regenerate(RegenerateOptions(design.root, folder), progress=build_step)
    say(f"mount geometry {'from the cache' if built.manifest.cached else 'built'}; building the scene")
    mesh = TaggedMesh.load(built.folder / built.manifest.mesh)
    check_finish_parts(design.mount, mesh.parts)
    scene = build_scene(design.prescription, mesh, spec)
    return Prepared(design, spec, built, scene)


def prepare(design_dir: Path, scene_path: Path, geometry: Path | None = None,
            stage: Callable[[str], None] | None = None,
            build_step: Callable[[str, int, int], None] | None = None) -> Prepared:
    """Load, regenerate (cached) and build; stage(text) tells what it is doing."""
    design, spec = read_inputs(design_dir, scene_file(design_dir, scene_path), stage)
    return build(design, spec, geometry, stage, build_step)


__all__ = ["Prepared", "prepare", "read_inputs", "build", "scene_file"]
