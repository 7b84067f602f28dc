"""The results store: one SQLite row per finished run, so `history` and `compare` can look back.

One file per design folder by default (`DESIGN/.lensmount/runs.sqlite`); `--store PATH`
or the environment variable `LENSMOUNT_STORE` points several designs at a shared one.
Each run is one INSERT in one transaction: an interrupted writer leaves no half row.
The database runs in WAL mode with a busy timeout, so two simulations finishing at
the same moment both land (one waits for the other's few milliseconds).

A row's files never change afterwards: `record` copies the run's artefacts (summary.json,
irradiance.exr, preview.png, report.html, paths.npz) into a folder of the row's own,
`rows/ID/` beside the store file, and the row points there. The run's `--out` folder stays the
live one: `simulate --resume` adds passes to it (how a run is made more precise), and
the next row records the longer run without touching the earlier row's numbers. (Refusing to
resume into a folder a row owns would forbid exactly that.) The checkpoint is not copied: it
is the size of all the pass sums and only the live run resumes from it.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sqlite3
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from lensmount.atomic import atomic_path
from lensmount.errors import InputError

ENV = "LENSMOUNT_STORE"
DEFAULT_NAME = Path(".lensmount") / "runs.sqlite"
BUSY_TIMEOUT_MS = 60_000
ROWS = "rows"  # beside the store file: rows/ID/ holds the artefacts a row points at
INPUTS = "inputs"  # beside the store file: inputs/SHA256 holds each input file a run read, by its content
COPIES = "designs"  # in INPUTS: designs/KEY/ is a run's input files put back together (`restore_inputs`)
ORIGIN = "origin.txt"  # in a row's folder: the run's own output folder, where its checkpoint stays

_SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    created_utc TEXT NOT NULL,
    design_path TEXT NOT NULL,
    design_name TEXT NOT NULL,
    scene_name TEXT NOT NULL,
    scene_path TEXT NOT NULL,
    lens_sha256 TEXT NOT NULL,
    mount_sha256 TEXT NOT NULL,
    scene_sha256 TEXT NOT NULL,
    input_hash TEXT NOT NULL,
    git_commit TEXT,
    git_dirty INTEGER,
    git_commit_time INTEGER,
    lensmount_version TEXT NOT NULL,
    command_line TEXT NOT NULL,
    method TEXT NOT NULL,
    seed INTEGER NOT NULL,
    passes INTEGER NOT NULL,
    photons INTEGER NOT NULL,
    time_s REAL NOT NULL,
    stray_fraction REAL,
    stray_fraction_std_error REAL,
    stray_fraction_bias_bound REAL,
    per_part TEXT NOT NULL,
    warnings TEXT NOT NULL,
    out_dir TEXT NOT NULL,
    summary_path TEXT NOT NULL,
    image_path TEXT NOT NULL,
    preview_path TEXT NOT NULL,
    condition_sha256 TEXT
);
CREATE INDEX IF NOT EXISTS runs_by_design ON runs (design_path, scene_name);
CREATE INDEX IF NOT EXISTS runs_by_input ON runs (input_hash);
"""
# Columns added since the first schema: (name, SQL type); a store made before gets them (NULL in old rows).
_ADDED = (("condition_sha256", "TEXT"),)


@dataclass(frozen=True)
class RunRecord:
    """One stored run (a row of `runs`)."""

    id: int
    created_utc: str
    design_path: str
    design_name: str
    scene_name: str
    scene_path: str
    lens_sha256: str
    mount_sha256: str
    scene_sha256: str
    input_hash: str
    git_commit: str | None
    git_dirty: bool | None
    git_commit_time: int | None
    lensmount_version: str
    command_line: str
    method: str
    seed: int
    passes: int
    photons: int
    time_s: float
    stray_fraction: float | None
    stray_fraction_std_error: float | None
    stray_fraction_bias_bound: float | None
    per_part: dict
    warnings: list
    out_dir: str
    summary_path: str
    image_path: str
    preview_path: str
    condition_sha256: str | None = None  # the test condition (provenance.condition_sha256); None: an older row

    @classmethod
    def from_row(cls, row: sqlite3.Row) -> "RunRecord":
        d = dict(row)
        d["per_part"] = json.loads(d["per_part"])
        d["warnings"] = json.loads(d["warnings"])
        d["git_dirty"] = None if d["git_dirty"] is None else bool(d["git_dirty"])
        return cls(**d)


def default_path(design_dir: str | Path, override: str | Path | None = None) -> Path:
    """--store PATH, else $LENSMOUNT_STORE, else DESIGN/.lensmount/runs.sqlite."""
    if override is not None:
        return Path(override)
    if os.environ.get(ENV):
        return Path(os.environ[ENV])
    return Path(design_dir).resolve() / DEFAULT_NAME


def _create(path: Path) -> None:
    """A new store appears whole, its schema in it (made beside it, then linked into place; of two
    processes creating it at once, one wins): a store of 0 bytes is damage, never one being made."""
    if path.exists():
        return
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        db = sqlite3.connect(tmp)
        db.execute("PRAGMA journal_mode = WAL")
        db.executescript(_SCHEMA)
        db.close()
        with contextlib.suppress(FileExistsError):
            os.link(tmp, path)
    finally:
        for leftover in (tmp, tmp + "-wal", tmp + "-shm"):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(leftover)


class Store:
    """The SQLite file of runs. Use as a context manager or call `close()`."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if self.path.is_file() and self.path.stat().st_size == 0:  # SQLite would take it for a new, empty store
            raise self._error(sqlite3.DatabaseError("it is empty, 0 bytes: the runs it held are gone"))
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            _create(self.path)
            self.db = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_MS / 1000, isolation_level=None)
            self.db.row_factory = sqlite3.Row
            self.db.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
            self.db.execute("PRAGMA journal_mode = WAL")
            self.db.executescript(_SCHEMA)
            have = {row["name"] for row in self.db.execute("PRAGMA table_info(runs)")}
            for name, kind in _ADDED:
                if name not in have:
                    try:
                        self.db.execute(f"ALTER TABLE runs ADD COLUMN {name} {kind}")
                    except sqlite3.OperationalError as exc:  # another process added it a moment ago
                        if "duplicate column" not in str(exc):
                            raise
            damage = [row[0] for row in self.db.execute("PRAGMA quick_check")]
        except sqlite3.OperationalError as exc:
            raise self._error(exc) from None
        except (OSError, sqlite3.Error) as exc:
            raise InputError(f"cannot open the results store ({exc})", file=str(self.path), field="--store",
                             valid=f"a writable SQLite file path (--store PATH or ${ENV}), or a store that is not "
                                   "damaged: move a damaged one aside (its runs' result folders stay as they "
                                   "are) or run with --no-record") from None
        if damage != ["ok"]:
            self.db.close()
            raise self._error(sqlite3.DatabaseError("; ".join(map(str, damage[:3]))))

    def _error(self, exc: sqlite3.Error) -> InputError:
        """A store that another process holds locked longer than the busy timeout, or a damaged one."""
        if "locked" in str(exc) or "busy" in str(exc):
            return InputError(f"the results store stayed locked by another process for {BUSY_TIMEOUT_MS // 1000} s "
                              f"({exc})", file=str(self.path), field="--store",
                              valid="wait for the other lensmount to finish and run again, use another --store, "
                                    "or --no-record")
        return InputError(f"the results store is damaged ({exc})", file=str(self.path), field="--store",
                          valid="move it aside (its runs' result folders stay as they are; history and compare "
                                "forget them) and run again, or run with --no-record")

    def __enter__(self) -> "Store":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.db.close()

    def record(self, summary: dict, paths: dict[str, Path]) -> int:
        """Insert one finished run from its summary (with `provenance`) and output paths; its id."""
        p = summary["provenance"]
        row = {
            "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            **{k: p[k] for k in ("design_path", "design_name", "scene_name", "scene_path", "lens_sha256",
                                 "mount_sha256", "scene_sha256", "git_commit", "git_commit_time",
                                 "lensmount_version", "command_line")},
            "git_dirty": None if p["git_dirty"] is None else int(p["git_dirty"]),
            "condition_sha256": p.get("condition_sha256") or None,
            "input_hash": summary["input_hash"], "method": summary["method"], "seed": summary["seed"],
            "passes": summary["passes"], "photons": summary["photons"], "time_s": summary["time_s"],
            "stray_fraction": summary.get("stray_fraction"),
            "stray_fraction_std_error": summary.get("stray_fraction_std_error"),
            "stray_fraction_bias_bound": summary.get("stray_fraction_bias_bound"),
            "per_part": json.dumps(summary.get("per_part", {}), sort_keys=True, allow_nan=False),
            "warnings": json.dumps(list(summary.get("warnings", []))),
            "out_dir": "", "summary_path": "", "image_path": "", "preview_path": "",  # set once the id is known
        }
        keys = ", ".join(row)
        marks = ", ".join(f":{k}" for k in row)
        # BEGIN IMMEDIATE takes the write lock up front (waiting up to the busy timeout),
        # so the insert and the row's files either land whole or not at all.
        try:
            self.db.execute("BEGIN IMMEDIATE")
        except sqlite3.Error as exc:
            raise self._error(exc) from None
        try:
            run_id = int(self.db.execute(f"INSERT INTO runs ({keys}) VALUES ({marks})", row).lastrowid)
            kept = self._keep(run_id, paths)
            self.db.execute("UPDATE runs SET out_dir = ?, summary_path = ?, image_path = ?, preview_path = ? "
                            "WHERE id = ?", (str(kept), str(kept / Path(paths["json"]).name),
                                             str(kept / Path(paths["exr"]).name),
                                             str(kept / Path(paths["png"]).name), run_id))
            self.db.execute("COMMIT")
        except BaseException as exc:
            self.db.execute("ROLLBACK")
            if isinstance(exc, sqlite3.Error):
                raise self._error(exc) from None
            raise
        return run_id

    def _keep(self, run_id: int, paths: dict[str, Path]) -> Path:
        """Copy the run's artefacts into rows/ID/ (written whole under a temporary name, then renamed)."""
        folder = self.path.resolve().parent / ROWS / str(run_id)
        partial = folder.with_name(f".{run_id}.partial")
        shutil.rmtree(partial, ignore_errors=True)
        partial.mkdir(parents=True)
        for path in paths.values():
            if Path(path).is_file():
                shutil.copy2(path, partial / Path(path).name)
        # Where the run lives on (its checkpoint is not copied): what `compare --until-decided` resumes.
        (partial / ORIGIN).write_text(str(Path(paths["json"]).resolve().parent) + "\n")
        shutil.rmtree(folder, ignore_errors=True)  # a folder of a rolled-back id that is being reused
        partial.rename(folder)
        return folder

    def keep_inputs(self, contents: dict[str, bytes]) -> None:
        """Keep a run's input files (SHA-256 → bytes) in inputs/, each once by its content: `restore_inputs`
        puts them back together after the design folder has moved on, so a run of an earlier revision can
        still be continued."""
        folder = self.path.resolve().parent / INPUTS
        for digest, data in contents.items():
            if not (folder / digest).is_file():
                with atomic_path(folder / digest) as tmp:
                    tmp.write_bytes(data)

    def restore_inputs(self, inputs: dict[str, str], key: str, marker: tuple[str, str]) -> Path | None:
        """The files `inputs` names (name → SHA-256) put back together in inputs/designs/KEY/, with the
        file `marker` (name, text) beside them; None when the store does not hold them all. Made whole
        under a temporary name, then renamed; made once, then reused."""
        kept = self.path.resolve().parent / INPUTS
        copy = kept / COPIES / key
        if copy.is_dir():
            return copy
        if not inputs or not all((kept / digest).is_file() for digest in inputs.values()):
            return None
        if any(Path(name).is_absolute() or os.path.normpath(name).split(os.sep)[0] == ".." for name in inputs):
            return None  # every name stays inside the copy (a damaged record is no way out of it)
        partial = copy.with_name(f".{key}.partial.{os.getpid()}")
        shutil.rmtree(partial, ignore_errors=True)
        for name, digest in inputs.items():
            (partial / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(kept / digest, partial / name)
        (partial / marker[0]).write_text(marker[1], encoding="utf-8")
        try:
            partial.rename(copy)
        except OSError:  # another process made it a moment ago
            shutil.rmtree(partial, ignore_errors=True)
        return copy

    def runs(self, design_path: str | Path | None = None, scene_name: str | None = None,
             input_hash: str | None = None, condition_sha256: str | None = None) -> list[RunRecord]:
        """Stored runs matching the filters, oldest first (`condition_sha256`: runs of that test
        condition, and older rows that did not record theirs)."""
        where, args = [], []
        if design_path is not None:
            where.append("design_path = ?")
            args.append(str(Path(design_path).resolve()))
        if scene_name is not None:
            where.append("scene_name = ?")
            args.append(scene_name)
        if input_hash is not None:
            where.append("input_hash = ?")
            args.append(input_hash)
        if condition_sha256 is not None:
            where.append("(condition_sha256 = ? OR condition_sha256 IS NULL)")
            args.append(condition_sha256)
        sql = "SELECT * FROM runs" + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY id"
        try:
            return [RunRecord.from_row(r) for r in self.db.execute(sql, args)]
        except (sqlite3.Error, ValueError, TypeError) as exc:  # ValueError: a damaged row's JSON
            raise self._error(sqlite3.DatabaseError(str(exc))) from None


__all__ = ["Store", "RunRecord", "default_path", "ENV"]
