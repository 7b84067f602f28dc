"""Write files so a reader never sees half of one: temp file in the same folder, then rename.

A JSON file that another command reads back (summary.json, regenerate's manifest.json) carries
the sha256 of its own content (`with_checksum`, `checksum_holds`), so a flipped bit that still
parses is seen as damage rather than read as another number.

A folder of outputs that belong together (regenerate's STEP files, mesh and manifest) is built
in a temp folder beside it and swapped in whole (`atomic_dir`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import signal
import tempfile
import zipfile
import zlib
from pathlib import Path

import numpy as np


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, mode: int = 0o644):
    """Yield a temp path beside `path`; on success it is renamed onto `path`, on error removed.

    The temp name keeps no extension of its own (`.NAME.XXXX.tmp`), so writers that
    append one (numpy adds `.npz` to names) must be given an open file instead.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, mode)  # mkstemp creates 0600; results are for other tools and people too
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write UTF-8 text atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


# What numpy and zipfile raise on a damaged .npz (truncated, emptied, a flipped bit: the zip's CRCs see
# those in the data; a flip in a header gives an unknown compression method, a bogus "encrypted" flag,
# a size that does not fit): readers turn these into an InputError naming the file.
NPZ_DAMAGE = (OSError, EOFError, ValueError, KeyError, IndexError, TypeError, zipfile.BadZipFile, zlib.error,
              NotImplementedError, RuntimeError, OverflowError, MemoryError)


def write_npz(path: str | os.PathLike, *, compressed: bool = False, **arrays) -> None:
    """Write a numpy .npz atomically."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        (np.savez_compressed if compressed else np.savez)(fh, **arrays)


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike):
    """Yield a new temp folder beside `path`; on success it replaces `path` whole, on error (or a
    signal) it is removed and `path` is as it was. What the old folder holds and the new one does
    not (a cache, the user's own files) moves over. SIGINT and SIGTERM wait the few renames of the swap.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp"))
    os.chmod(tmp, 0o755)  # mkdtemp makes it 0700
    old = tmp.with_name(tmp.name + ".old")
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        if path.exists():
            for entry in path.iterdir():
                if not (tmp / entry.name).exists():
                    os.rename(entry, tmp / entry.name)
            os.rename(path, old)
        os.rename(tmp, path)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
    shutil.rmtree(old, ignore_errors=True)


CHECKSUM = "sha256"  # the key under which a JSON document carries the checksum of the rest of it


def _digest(data: dict) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True, allow_nan=False).encode()).hexdigest()


def with_checksum(data: dict) -> dict:
    """`data` and, under CHECKSUM, the sha256 of its canonical JSON (sorted keys)."""
    content = {k: v for k, v in data.items() if k != CHECKSUM}  # a document read back carries its old one
    return {**content, CHECKSUM: _digest(content)}


def checksum_holds(data: dict) -> bool:
    """Whether a JSON document read back is as written: its CHECKSUM (removed from `data` here)
    agrees with the rest. A document without one (written by hand or by an older lensmount) holds."""
    if not isinstance(data, dict):
        return False
    claimed = data.pop(CHECKSUM, None)
    return claimed is None or claimed == _digest(data)
