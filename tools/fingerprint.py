"""The numbers a refactor must not move: short runs of every example scene and `inspect` of the corpus.

    .venv/bin/python tools/fingerprint.py OUT.json          # then diff two OUT.json files

Runs the CLI (not the API, whose import paths a re-cut may move): every example design is
regenerated once, each of its scenes simulated for a few small passes at a fixed seed, and every
corpus lens file inspected. What it keeps is every number in summary.json except wall/CPU times
and provenance, and inspect's printed table; two fingerprints of the same code are equal.
"""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
LM = [str(Path(sys.executable).parent / "lensmount")]
VOLATILE = re.compile(r"provenance|time|second|wall|cpu|date|commit|command|host|python|version|elapsed|rate|path|store|out|"
                      r"created|_s$|eta|throughput|workers|geometry|sha256", re.I)  # sha256 covers times too


def stable(value):
    """The summary without times and provenance (numbers as repr, so equality is bit equality)."""
    if isinstance(value, dict):
        return {k: stable(v) for k, v in sorted(value.items()) if not VOLATILE.search(k)}
    if isinstance(value, list):
        return [stable(v) for v in value]
    if isinstance(value, float):
        return repr(value)
    return value


def run(args, cwd):
    done = subprocess.run(LM + args, cwd=cwd, capture_output=True, text=True)
    return done.returncode, done.stdout


def mesh_digest(path: Path) -> str:
    """The mesh's arrays to 1 nm (not the .npz's bytes: the CAD kernel's tessellation gives a coordinate of 0.0
    in one build and -5e-29 in the next, which changes the compressed file's size but no number that matters)."""
    digest = hashlib.sha256()
    with np.load(path, allow_pickle=False) as arrays:
        for key in sorted(arrays.files):
            a = arrays[key]
            if a.dtype.kind == "f":
                a = np.round(a, 6) + 0.0  # mm to 1 nm; + 0.0 turns -0.0 into 0.0
            digest.update(key.encode() + str(a.dtype).encode() + str(a.shape).encode() + a.tobytes())
    return digest.hexdigest()[:16]


def main(out: Path) -> None:
    found = {}
    with tempfile.TemporaryDirectory() as tmp:
        for design in sorted((ROOT / "examples").iterdir()):
            geometry = Path(tmp) / design.name
            code, _ = run(["regenerate", str(design), "--out", str(geometry)], ROOT)
            found[f"{design.name}/regenerate"] = code
            mesh = geometry / "mesh.npz"
            found[f"{design.name}/mesh"] = mesh_digest(mesh) if mesh.exists() else None
            for scene in sorted((design / "scenes").glob("*.toml")):
                run_out = Path(tmp) / f"{design.name}-{scene.stem}"
                code, _ = run(["simulate", str(design), "--scene", str(scene), "--geometry", str(geometry),
                               "--out", str(run_out), "--passes", "2", "--photons-per-pass", "4000",
                               "--seed", "7", "--no-record"], ROOT)
                summary = run_out / "summary.json"
                found[f"{design.name}/{scene.stem}"] = (
                    stable(json.loads(summary.read_text())) if summary.exists() else f"exit {code}")
        for lens in sorted((ROOT / "tests/optics/corpus").rglob("*.zmx")):
            code, text = run(["inspect", str(lens)], ROOT)
            found[f"corpus/{lens.relative_to(ROOT / 'tests/optics/corpus')}"] = [code, text]
    out.write_text(json.dumps(found, indent=1, sort_keys=True))
    print(f"{len(found)} fingerprints -> {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
