"""Content-addressed cache of regenerate outputs.

Key: `Design.input_hash` (lens file, mount.toml, user templates, lensmount version).
Store: `OUT/.cache/<key>/` holds a complete copy of the outputs (hard links where
the file system allows, so no extra space) of the files `Manifest.files()` lists (one list: what a
build writes is what its checksums cover and what is kept here) and manifest.json. A re-run with the same key restores OUT from there without touching
the CAD kernel; switching a parameter back and forth restores the earlier outputs.
Delete `OUT/.cache` to empty it.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

CACHE_DIR = ".cache"


def cache_dir(out_dir: Path, key: str) -> Path:
    return Path(out_dir) / CACHE_DIR / key


def _files(root: Path) -> list[Path]:
    rels = (p.relative_to(root) for p in root.rglob("*") if p.is_file())
    return sorted(r for r in rels if CACHE_DIR not in r.parts)


def _same(a: Path, b: Path) -> bool:
    try:
        if os.path.samefile(a, b):
            return True
        sa, sb = a.stat(), b.stat()
        if sa.st_size != sb.st_size:
            return False
        return a.read_bytes() == b.read_bytes()
    except OSError:
        return False


def place(src: Path, dst: Path) -> None:
    """dst becomes src's content, atomically (hard link, or copy), unless it already is."""
    if dst.exists() and _same(src, dst):
        return
    dst.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=dst.parent, suffix=".tmp")
    os.close(fd)
    os.unlink(tmp)
    try:
        try:
            os.link(src, tmp)
        except OSError:
            shutil.copy2(src, tmp)
        os.replace(tmp, dst)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def store(out_dir: Path, key: str, relpaths: list[str]) -> None:
    """Put the listed outputs of OUT into the cache under key."""
    target = cache_dir(out_dir, key)
    for rel in relpaths:
        place(Path(out_dir) / rel, target / rel)


def restore(entry: Path, out_dir: Path) -> None:
    """Fill the (new, empty) folder OUT with the outputs of a cache entry (`cache_dir`), whose
    manifest the caller has checked against the files' checksums."""
    for rel in _files(entry):
        place(entry / rel, Path(out_dir) / rel)


__all__ = ["cache_dir", "store", "restore", "place", "CACHE_DIR"]
