"""Results folders and store rows for loop tests, without running the tracer.

The loop's logic (provenance, store, history order, verdicts, exit codes) does not
depend on how the numbers were made; the physics of the numbers is tested elsewhere.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np

from lensmount.run.results import write_exr, write_summary

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


def provenance(design: Path, scene: str = "case1", **git) -> dict:
    design = Path(design).resolve()
    base = {"design_path": str(design), "design_name": design.name, "scene_path": str(design / f"{scene}.toml"),
            "scene_name": scene, "lens_file": "lens.toml", "lens_sha256": "l" * 64, "mount_sha256": "m" * 64,
            "scene_sha256": "s" * 64, "git_commit": None, "git_dirty": None, "git_commit_time": None,
            "lensmount_version": "0.1.0", "command_line": "lensmount simulate"}
    return {**base, **git}


def write_run(folder: Path, value: float, std_error: float | None, *, passes: int = 16, parts=None,
              prov: dict | None = None, input_hash: str = "0" * 16, image=None, effects=("scatter",)) -> dict:
    """A results folder: summary.json (value ± std_error) and an irradiance.exr whose flux matches."""
    parts = parts or {"barrel": (value, std_error)}
    img = np.full((4, 6), value, np.float64) if image is None else image
    summary = {
        "method": "bidirectional", "seed": 1, "effects": list(effects), "effects_skipped": [], "passes": passes,
        "photons": passes * 1000, "time_s": float(passes), "stray_fraction": value,
        "stray_fraction_std_error": std_error, "stray_flux_mm2": value, "stray_flux_std_error_mm2": std_error,
        "per_part": {k: {"fraction": v, "std_error": e, "flux_mm2": v} for k, (v, e) in parts.items()},
        "input_hash": input_hash, "provenance": prov or provenance(folder), "warnings": [],
    }
    folder.mkdir(parents=True, exist_ok=True)
    write_exr(folder / "irradiance.exr", img, img[None], ["barrel"])
    (folder / "preview.png").write_bytes(b"")
    write_summary(folder / "summary.json", summary)
    return summary


def paths(folder: Path) -> dict:
    return {"exr": folder / "irradiance.exr", "png": folder / "preview.png", "json": folder / "summary.json"}


def git(repo: Path, *args: str, date: str = "2026-01-01T12:00:00Z") -> str:
    env = {"GIT_AUTHOR_DATE": date, "GIT_COMMITTER_DATE": date, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@x",
           "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@x", "PATH": "/usr/bin:/bin", "HOME": str(repo)}
    return subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True, text=True,
                          env=env).stdout.strip()
