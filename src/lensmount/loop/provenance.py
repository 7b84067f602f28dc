"""What reproduces a run: the input files' hashes, the design's git revision, the command.

A run is only comparable with another when we know what it was computed from, so
every summary.json and every row of the results store carries this record.
"""

from __future__ import annotations

import hashlib
import os
import shlex
import subprocess
import sys
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
    step_sha256: dict[str, str] = field(default_factory=dict)  # STEP part file (design-relative) → SHA-256

    def to_dict(self) -> dict:
        return asdict(self)


def collect(root: str | Path, lens_path: Path, mount_path: Path, scene_path: str | Path,
            template_paths: list[Path] = (), argv: list[str] | None = None, step_paths: list[Path] = ()) -> Provenance:
    """The provenance of a run of `scene_path` on the design folder `root` (its lens, mount,
    user template and STEP part files, as `lensmount.design.folder.Design` names them)."""
    root = Path(root).resolve()
    scene_path = Path(scene_path).resolve()
    git = git_state(root, [lens_path, mount_path, scene_path, *template_paths, *step_paths])
    argv = sys.argv if argv is None else argv
    return Provenance(
        design_path=str(root), design_name=root.name, scene_path=str(scene_path), scene_name=scene_path.stem,
        lens_file=Path(lens_path).name, lens_sha256=file_sha256(lens_path), mount_sha256=file_sha256(mount_path),
        scene_sha256=file_sha256(scene_path), git_commit=git.commit if git else None,
        git_dirty=git.dirty if git else None, git_commit_time=git.commit_time if git else None,
        lensmount_version=lensmount.__version__, command_line=shlex.join(argv),
        step_sha256={os.path.relpath(Path(p).resolve(), root): file_sha256(p) for p in step_paths})


__all__ = ["Provenance", "GitState", "collect", "git_state", "commit_order", "resolve_revision", "file_sha256"]
