"""`lensmount regenerate DESIGN [--out DIR]` and `lensmount init DIR --example NAME | --lens FILE`.

Parses, calls lensmount.cad / lensmount.design, prints. No geometry here.
"""

from __future__ import annotations

import shutil
import sys
import textwrap
from pathlib import Path
from typing import Optional

import tomli_w
import typer

from lensmount.atomic import atomic_path, write_text
from lensmount.cli.commands import COMMANDS, CommandLine, fail
from lensmount.cli.check import run_check
from lensmount.cli.options import GlassCatalogs
from lensmount.cli.simulate import TerminalObserver
from lensmount.design.edges import changes_aperture, clip_gap, what_the_glass_allows
from lensmount.design.lens import load_lens_and_clips
from lensmount.design.mount import parse_mount
from lensmount.errors import InputError
from lensmount.loop.regenerate import RegenerateOptions, regenerate as run

EXAMPLE_FILES = ("lens.toml", "lens.zmx", "mount.toml", "finishes.toml")


def examples_root() -> Path:
    """The examples shipped inside the package (the repo's top-level `examples` links here)."""
    return Path(__file__).resolve().parent.parent / "examples"


@COMMANDS.register("regenerate", CommandLine)
def regenerate(
    design: Path = typer.Argument(..., help="design folder: lens.toml (or lens.zmx), mount.toml, scenes/"),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder (default DESIGN/build)"),
    no_cache: bool = typer.Option(False, "--no-cache", help="rebuild even when the inputs are unchanged"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar"),
    linear_tolerance: Optional[float] = typer.Option(
        None, "--linear-tolerance", help="tessellation chord deviation, mm (overrides mount.toml)"),
    angular_tolerance: Optional[float] = typer.Option(
        None, "--angular-tolerance", help="tessellation angular deflection, degrees (overrides mount.toml)"),
    check: bool = typer.Option(False, "--check", help="then run `lensmount check` on the result "
                               "(exit 1 when a lit wall is seen)"),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """Build the mount: assembly.step, parts/NAME.step, mesh.npz (tagged triangles), manifest.json.

    Progress goes to stderr: bars on a terminal, one line per finished CAD step (with its
    seconds) when stderr is a file or a pipe. The outputs are built beside the folder and
    swapped in whole: a refused or stopped regenerate leaves it as it was."""
    tess = {k: v for k, v in (("linear_tolerance_mm", linear_tolerance),
                              ("angular_tolerance_deg", angular_tolerance)) if v is not None}
    options = RegenerateOptions(design, out, use_cache=not no_cache, tessellation=tess)
    observer = TerminalObserver(live=sys.stderr.isatty())
    try:
        result = run(options, None if quiet else observer.build_step)
    except InputError as error:
        observer.close()
        fail(error)
    finally:
        observer.close()
    manifest, target, tri = result.manifest, result.folder, result.triangles
    how = "from the cache (inputs unchanged)" if manifest.cached else "built"
    typer.echo(f"{target}: {len(manifest.parts)} parts, {tri} triangles, {how}; input hash {manifest.input_hash[:12]}")
    for warning in manifest.warnings:
        typer.echo(f"warning: {warning}")
    for note in manifest.notes:
        typer.echo(f"note: {note}")
    if check:
        try:
            passed = run_check(design, target, None)
        except InputError as error:
            fail(error)
        if not passed:
            raise typer.Exit(code=1)


@COMMANDS.register("init", CommandLine)
def init(
    directory: Path = typer.Argument(..., help="new design folder"),
    example: str = typer.Option("double-gauss-360", "--example", "-e", help="example to copy"),
    lens: Optional[Path] = typer.Option(
        None, "--lens", "-l", help="start from this lens (.zmx or lens.toml) instead of an example: mount.toml, "
        "finishes.toml and a case-2 scene are derived from it (mirrors included: cells in a straight barrel), "
        "checked as regenerate checks them; exit 2 with the reasons when no mount the planner knows builds"),
    force: bool = typer.Option(False, "--force", help="write into an existing non-empty folder"),
    allow_vignetting: bool = typer.Option(
        False, "--allow-vignetting", help="with --lens: an element whose faces cross inside the beam is edged "
        "where its glass allows, whatever that vignettes (lens_edge.allow_vignetting; without it init refuses, "
        "saying what the glass allows and the vignetting per field)"),
    glass_catalog: GlassCatalogs = [],
) -> None:
    """Scaffold a design folder (lens file, mount.toml, finishes.toml, scenes/) from an example or from a lens file.

    The design is the lens, the mount and finishes.toml (finishes, coatings, which faces get which),
    shared by every scene; a scene (scenes/*.toml) is a test condition: source, detector, effects, run."""
    try:
        directory = Path(directory)
        if directory.exists() and any(directory.iterdir()) and not force:
            raise InputError("the folder exists and is not empty", file=str(directory),
                             valid="a new or empty folder, or --force")
        if lens is not None:
            scenes = _init_from_lens(directory, Path(lens), allow_vignetting)
            again = "".join(f" --glass-catalog {c}" for c in glass_catalog)   # the lens file cannot name them
            made = ["mount.toml", "finishes.toml"] + [f"scenes/{s}.toml" for s in scenes]
            typer.echo(f"{directory}: design folder from {lens} ({', '.join(made[:-1])} and {made[-1]} derived from "
                       f"the lens); next: lensmount regenerate {directory}{again}")
            return
        root = examples_root()
        names = sorted(p.name for p in root.iterdir() if (p / "mount.toml").is_file())
        src = root / example
        if example not in names:
            raise InputError(f"unknown example {example!r}", field="--example", valid=", ".join(names))
    except InputError as error:
        fail(error)
    directory.mkdir(parents=True, exist_ok=True)
    for name in EXAMPLE_FILES:
        if (src / name).is_file():
            shutil.copy2(src / name, directory / name)
    for sub in ("scenes", "templates"):
        if (src / sub).is_dir():
            shutil.copytree(src / sub, directory / sub, dirs_exist_ok=True)
    typer.echo(f"{directory}: design folder from example {example!r}; next: lensmount regenerate {directory}")


def _lens_name(p, lens: Path) -> str:
    return p.name if p.name not in ("", "lens") else lens.stem


def _starter_for_lens(lens: Path):
    """(prescription, mount.toml dict, why no mount builds or None, the clips the glass sets or ()).
    When the file's elements need clips that change the design's aperture (design.edges: faces crossing
    inside the beam), or no mount builds and an element's faces come closer than the mount's least edge
    inside the beam, each such element is edged where its glass allows at the mount's own least edge,
    and the mount says so (lens_edge.allow_vignetting), as regenerate then loads the lens."""
    # lazy: keeps lensmount --help from loading cad and matplotlib
    from lensmount.cad.starter import least_edge, starter_mount

    prescription, clips = load_lens_and_clips(lens, max_clip_vignetting=None)
    name, gap = _lens_name(prescription, lens), least_edge(prescription)

    def sized_by_glass(gap: float):
        return load_lens_and_clips(lens, clip_edge_mm=gap, max_clip_vignetting=None, clip_thin=True)

    if not changes_aperture(clips):   # the import's own clips (if any), within what it allows: load_lens's lens
        mount, problem = starter_mount(prescription, name)
        if problem is None or not sized_by_glass(gap)[1]:
            return prescription, mount, problem, ()
    for _ in range(2):   # the search may change the chamfers: the glass's size follows the mount's least edge
        prescription, clips = sized_by_glass(gap)
        mount, problem = starter_mount(prescription, name)
        mount["lens_edge"]["allow_vignetting"] = True
        if problem or abs(clip_gap(parse_mount(mount)) - gap) < 1e-9:
            break
        gap = clip_gap(parse_mount(mount))
    return prescription, mount, problem, clips


def _init_from_lens(directory: Path, lens: Path, allow_vignetting: bool = False) -> list[str]:
    """Copy the lens, write the derived mount.toml, finishes.toml (mirrors: their scatter included) and
    case-2 scene (the sun, or for a finite object a point outside its field), and for a finite object the
    object-lambertian scene (everything checked before writing); the names of the scenes written.
    InputError, with nothing written, when no mount that builds was found, or when one builds only with an
    element sized by its glass and `allow_vignetting` is not given."""
    # lazy: keeps lensmount --help from loading cad and matplotlib
    from lensmount.cad.starter import case2_scene, object_scene, starter_finishes

    prescription, mount, problem, clips = _starter_for_lens(lens)
    name = _lens_name(prescription, lens)
    glass = f"; its glass limits it: {what_the_glass_allows(clips)}" if clips else ""
    if problem:
        raise InputError(f"no mount that builds was found for this lens: {problem}{glass}", file=str(lens),
                         valid="a lens whose elements leave room for seats, spacers and the diaphragm; or "
                               "start from an example (`lensmount init DIR --example NAME`) and edit mount.toml")
    if clips and not allow_vignetting:
        raise InputError(f"a mount builds for this lens only with an element smaller than the beam of its full "
                         f"field: {what_the_glass_allows(clips)}", file=str(lens), field="--allow-vignetting",
                         valid=f"`lensmount init {directory} --lens {lens} --allow-vignetting` to build that mount "
                               "(lens_edge.allow_vignetting = true; regenerate and check state the vignetting), "
                               "or a lens whose element is thicker at its edge")
    scene = case2_scene(prescription, mount, name)
    obj = object_scene(prescription, scene, name)
    target = "lens.zmx" if lens.suffix.lower() == ".zmx" else "lens.toml"
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "scenes").mkdir(exist_ok=True)
    header = f"# mount.toml derived by `lensmount init --lens {lens.name}` (lensmount.cad.starter); " \
             "keys: docs/mount-toml.md\n"
    bonded = [side for side in ("front", "rear") if mount["seats"][side] == "bonded"]
    if bonded:   # the last seat init tries: said where the engineer reads, not only in regenerate's notes
        said = (f"seats.{' and seats.'.join(bonded)} = 'bonded': the {' and '.join(bonded)} element held by an "
                "adhesive bead on its ground edge: no retainer or shoulder on its face builds (a clear aperture reaching "
                "the rim leaves no annulus for one; regenerate's notes give the sizes)")
        header += f"# {said}\n"
        typer.echo(f"note: {said}")
    if clips:   # allowed: said where the engineer reads the mount, not only in regenerate's notes
        said = f"lens_edge.allow_vignetting = true: {what_the_glass_allows(clips)}"
        header += "".join(f"# {line}\n" for line in textwrap.wrap(said, 110))
        typer.echo(f"note: {said}")
    write_text(directory / "finishes.toml", "# finishes.toml derived by `lensmount init` (lensmount.cad.starter): "
               "the design's finishes, coatings and which faces get which, shared by every scene\n"
               + tomli_w.dumps(starter_finishes(prescription)))
    write_text(directory / "scenes" / "case2-lambertian.toml", tomli_w.dumps(scene))
    if obj is not None:  # a finite object: the object itself as the source
        write_text(directory / "scenes" / "object-lambertian.toml", tomli_w.dumps(obj))
    write_text(directory / "mount.toml", header + tomli_w.dumps(mount))
    with atomic_path(directory / target) as tmp:  # byte for byte: a .zmx keeps its encoding
        tmp.write_bytes(lens.read_bytes())
    return ["case2-lambertian"] + (["object-lambertian"] if obj is not None else [])
