"""What reproduces a run: the input files' hashes, the design's git revision, the command.

A run is only comparable with another when we know what it was computed from, so
every summary.json and every row of the results store carries this record. It keeps the
two halves apart: the test condition (the scene's source, detector, effects and objects,
`condition`; not its run length) and the design (lens surfaces, mount keys, finishes and
user files, `design`), so `compare` refuses runs of different test conditions and lists
what changed in the design beside its verdict.
"""

from __future__ import annotations

import hashlib
import json
import math
import shlex
import subprocess
import sys
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

import lensmount


def file_sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass(frozen=True)
class GitState:
    """The design folder's revision: HEAD, whether the inputs differ from it, its commit time."""

    commit: str
    dirty: bool
    commit_time: int  # committer time, s since the epoch (orders revisions when the commit is gone)


def _git(directory: Path, *args: str) -> str | None:
    try:
        done = subprocess.run(["git", "-C", str(directory), *args], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout if done.returncode == 0 else None


def git_state(directory: str | Path, inputs: list[Path] | None = None) -> GitState | None:
    """HEAD of the repository holding `directory` and whether it is dirty, or None outside git.

    Dirty means `git status --porcelain` reports a change in the design folder's input
    files (`inputs`, default: the whole folder). Outputs written inside the folder
    (build/, .lensmount/) do not change what a run computes, so they do not count.
    """
    directory = Path(directory).resolve()
    head = _git(directory, "rev-parse", "HEAD")
    if head is None:
        return None
    paths = [str(Path(p).resolve()) for p in inputs] if inputs else [str(directory)]
    status = _git(directory, "status", "--porcelain", "--", *paths) or ""
    when = (_git(directory, "log", "-1", "--format=%ct", "HEAD") or "0").strip()
    return GitState(head.strip(), bool(status.strip()), int(when or 0))


def resolve_revision(directory: str | Path, revision: str) -> str | None:
    """The full commit id git gives a revision name (HEAD~2, a tag, a short id), None when it knows none."""
    out = _git(Path(directory).resolve(), "rev-parse", "--verify", "--quiet", f"{revision}^{{commit}}")
    return out.strip() if out else None


def commit_order(directory: str | Path) -> list[str]:
    """Commits reachable from HEAD, oldest first (empty outside git)."""
    out = _git(Path(directory).resolve(), "rev-list", "--topo-order", "--reverse", "HEAD")
    return out.split() if out else []


@dataclass(frozen=True)
class Provenance:
    """Everything summary.json and the store record about where a run came from."""

    design_path: str
    design_name: str
    scene_path: str
    scene_name: str
    lens_file: str
    lens_sha256: str
    mount_sha256: str
    scene_sha256: str
    git_commit: str | None
    git_dirty: bool | None
    git_commit_time: int | None
    lensmount_version: str
    command_line: str
    condition_sha256: str = ""
    finishes_sha256: str | None = None
    condition: dict = field(default_factory=dict)
    design: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)  # the run's input files: name in a copy of them → SHA-256
    scene_input: str = ""  # the scene's name among `inputs`

    def to_dict(self) -> dict:
        return asdict(self)


# In a folder restored from a run's stored inputs (`run.store.Store.restore_inputs`): that run's provenance.
# A run made there is the stored run continued, so it records the design and scene it was made from.
INPUTS_OF = ".lensmount-inputs-of.json"


def input_files(design, scene_path: str | Path, spec) -> tuple[dict[str, Path], str]:
    """Every file a run of `scene_path` on `design` reads, by the name it takes in a copy of them (relative
    to the design folder; a scene kept elsewhere goes to scene/ with the object files beside it), and the
    scene's name: lens, mount, finishes, user files and the glass catalogues in the folder, the scene and
    its objects' mesh files. A copy of these files is the design as it was when the run was made."""
    root = design.root.resolve()
    scene_path = Path(scene_path).resolve()
    catalogues = [Path(c) for c in design.prescription.glass_catalogs]
    found = [design.lens_path, design.mount_path, *([design.finishes_path] if design.finishes_path else []),
             *user_files(design), *catalogues]
    files = {str(p.resolve().relative_to(root)): p for p in found if p.is_file() and p.resolve().is_relative_to(root)}
    scene_dir = Path(str(scene_path.relative_to(root).parent)) if scene_path.is_relative_to(root) else Path("scene")
    files[str(scene_dir / scene_path.name)] = scene_path
    for obj in spec.objects:
        mesh = (scene_path.parent / obj.path) if obj.path and not Path(obj.path).is_absolute() else None
        if mesh is not None and mesh.is_file():  # (a mesh named by its absolute path is found as it is)
            files[str(scene_dir / obj.path)] = mesh
    return files, str(scene_dir / scene_path.name)


def condition_record(spec) -> dict:
    """The test condition of a scene (a SceneSpec, detector fitted to the housing) as flat
    'table.key' → value: source, detector, effects and objects; not the run length (a longer run
    of the same condition is the same test) nor the description."""
    return flatten(spec.model_dump(mode="json", include={"source", "detector", "effects", "objects"}))


def condition_sha256(spec) -> str:
    """The hash of a scene's test condition (`condition_record`): what runs must share to compare."""
    return digest(condition_record(spec))


def digest(record: dict) -> str:
    """SHA-256 of a flat record (key order free)."""
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()


def user_files(design) -> list[Path]:
    """The design's own files besides the lens, mount and finishes: user templates, STEP parts
    ([parts.NAME]) and measured BSDF data, and the STEP/STL files beside them (what a template may load)."""
    found = set(design.template_paths.values()) | set(design.step_paths.values())
    found |= {design.root / str(p["file"]) for p in _finish_tables(design).values()
              if isinstance(p, dict) and "file" in p}
    for folder in {design.root, *(p.parent for p in found)}:
        found |= {p for p in folder.glob("*") if p.suffix.lower() in (".step", ".stp", ".stl")}
    return sorted(p for p in found if p.is_file())


def _finish_tables(design) -> dict:
    """finishes.toml's [finishes] as written (a measured finish: its file name, not its table)."""
    path = design.finishes_path
    return tomllib.loads(path.read_text(encoding="utf-8")).get("finishes", {}) if path else {}


def design_record(design) -> dict:
    """What a run's design was, flat, for `compare` to list what changed: each lens surface's
    prescription ('lens.surface 3.radius'), every mount key ('mount.vanes.count'), the treatment
    ('finishes.black-paint.reflectance', 'coatings.default', 'assign.*') and each user file's hash."""
    def number(x):  # a flat surface's radius is infinite: JSON has no inf, summary.json none
        return x if x is None or math.isfinite(x) else str(x)

    lens = {f"surface {i + 1}": {"radius": number(s.radius), "thickness": number(s.thickness),
                                 "material": s.material, "conic": s.conic, "aspheric": list(s.aspheric),
                                 "clear_semi_diameter": number(s.clear_semi_diameter), "stop": s.is_stop,
                                 "coating": s.coating, "mirror": s.mirror}
                                | ({} if s.qtype is None else {"qtype": {"form": s.qtype.form,
                                                                         "norm_radius": s.qtype.norm_radius,
                                                                         "coefficients": list(s.qtype.coefficients)}})
            for i, s in enumerate(design.prescription.surfaces)}
    treatment = design.finishes.tables() | {"finishes": _finish_tables(design)}
    files = {str(p.relative_to(design.root)) if p.is_relative_to(design.root) else str(p): file_sha256(p)
             for p in user_files(design)}
    return flatten({"lens": lens, "mount": tomllib.loads(design.mount_path.read_text(encoding="utf-8")),
                    **treatment, "file": files})


def flatten(value, prefix: str = "") -> dict:
    """Nested tables → {'a.b.c': leaf}; lists stay leaves (a list of numbers is one value)."""
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out |= flatten(v, f"{prefix}.{k}" if prefix else str(k))
        return out
    if isinstance(value, (list, tuple)) and any(isinstance(v, dict) for v in value):
        return flatten({str(k): v for k, v in enumerate(value)}, prefix)
    return {prefix: list(value) if isinstance(value, tuple) else value}


_SECTIONS = {"lens": "lens", "finishes": "finish", "mount": "mount", "assign": "assignment", "coatings": "coating",
             "file": "file"}
_GROUPED = ("lens", "finishes")  # keys name a thing and its attribute: 'finishes.black-paint.reflectance'


def _shown(value) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "[" + ", ".join(_shown(v) for v in value) + "]"
    return "(none)" if value is None else str(value)


def design_changes(old: dict, new: dict) -> list[str]:
    """What changed between two design records (`design_record`), one line each, in the engineer's
    words: 'finish black-paint: reflectance 0.05 -> 0.2', 'mount vanes.count: 3 -> 5',
    'lens surface 4: radius 51.2 -> 52', 'file templates/hood.py: changed', 'finish gloss: added'."""
    lines, seen = [], set()
    for key in sorted(set(old) | set(new), key=lambda k: (list(_SECTIONS).index(k.split(".")[0])
                                                          if k.split(".")[0] in _SECTIONS else 99, k)):
        if old.get(key, _MISSING) == new.get(key, _MISSING):
            continue
        section, _, rest = key.partition(".")
        label = _SECTIONS.get(section, section)
        if section == "file":
            state = "added" if key not in old else "removed" if key not in new else "changed"
            lines.append(f"file {rest}: {state}")
            continue
        if section in _GROUPED:
            thing, _, attribute = rest.partition(".")
            group = f"{section}.{thing}."
            in_old = any(k.startswith(group) for k in old)
            in_new = any(k.startswith(group) for k in new)
            if not (in_old and in_new):
                if group not in seen:
                    seen.add(group)
                    lines.append(f"{label} {thing}: {'added' if in_new else 'removed'}")
                continue
            lines.append(f"{label} {thing}: {attribute} {_value(old, key)} -> {_value(new, key)}")
            continue
        lines.append(f"{label} {rest}: {_value(old, key)} -> {_value(new, key)}")
    return lines


def condition_changes(old: dict, new: dict) -> list[str]:
    """What differs between two test conditions (`condition_record`): 'source.off_axis_deg 7 -> 9'."""
    return [f"{key} {_value(old, key)} -> {_value(new, key)}" for key in sorted(set(old) | set(new))
            if old.get(key, _MISSING) != new.get(key, _MISSING)]


_MISSING = object()


def _value(record: dict, key: str) -> str:
    return _shown(record[key]) if key in record else "(not set)"


def collect(design, spec, scene_path: str | Path, argv: list[str] | None = None) -> Provenance:
    """The provenance of a run of `scene_path` (read as `spec`, its detector fitted) on `design`
    (a loaded `lensmount.design.folder.Design`)."""
    root = design.root.resolve()
    scene_path = Path(scene_path).resolve()
    argv = sys.argv if argv is None else argv
    if (root / INPUTS_OF).is_file():  # the stored inputs of a run: that run, continued
        recorded = json.loads((root / INPUTS_OF).read_text(encoding="utf-8"))
        known = {k: v for k, v in recorded.items() if k in Provenance.__dataclass_fields__}
        return Provenance(**known | {"command_line": shlex.join(argv)})
    finishes = design.finishes_path
    files, scene_input = input_files(design, scene_path, spec)
    git = git_state(root, [design.lens_path, design.mount_path, scene_path, *([finishes] if finishes else []),
                           *user_files(design)])
    condition = condition_record(spec)
    return Provenance(
        design_path=str(root), design_name=root.name, scene_path=str(scene_path), scene_name=scene_path.stem,
        lens_file=design.lens_path.name, lens_sha256=file_sha256(design.lens_path),
        mount_sha256=file_sha256(design.mount_path), scene_sha256=file_sha256(scene_path),
        git_commit=git.commit if git else None, git_dirty=git.dirty if git else None,
        git_commit_time=git.commit_time if git else None, lensmount_version=lensmount.__version__,
        command_line=shlex.join(argv), condition_sha256=digest(condition),
        finishes_sha256=file_sha256(finishes) if finishes else None, condition=condition,
        design=design_record(design), inputs={name: file_sha256(p) for name, p in files.items()},
        scene_input=scene_input)


__all__ = ["Provenance", "INPUTS_OF", "input_files", "GitState", "collect", "condition_record", "condition_sha256", "condition_changes", "design_changes", "design_record", "digest", "flatten", "user_files", "git_state", "commit_order", "resolve_revision", "file_sha256"]
