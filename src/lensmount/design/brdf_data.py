"""Measured BRDF files → points (ρ = |β − β0|, f) for `physics.bsdf.tabulated`.

Two formats:

* **Zemax tabular BSDF** (`.bsdf`, Radiant's BSDF data interchange format): header
  lines `Symmetry`, `SpectralContent`, `ScatterType`, `SampleRotation`, `AngleOfIncidence`,
  `ScatterAzimuth`, `ScatterRadial` (each a count, then the values on the next line), then
  `DataBegin`, and per angle of incidence a `TIS value` line followed by one row of BRDF
  values (one per radial angle) per azimuth, then `DataEnd`. Radial and azimuth angles
  are measured about the specular direction (which is what `AngleOfIncidence` gives).
  Only isotropic, monochrome BRDF data (one sample rotation) is taken.
* **CSV** with the header `incidence_deg,scatter_deg,brdf`: in-plane measurements, the
  scatter angle from the normal, positive on the specular side.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from lensmount.errors import InputError

CSV_COLUMNS = ("incidence_deg", "scatter_deg", "brdf")


def read_brdf(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(ρ, f) points of a measured BRDF file (.bsdf or .csv), scatter directions below the surface dropped."""
    path = Path(path)
    if not path.exists():
        raise InputError("BRDF data file not found", file=str(path), valid="a .bsdf (Zemax tabular) or .csv file")
    text = path.read_text(encoding="utf-8", errors="replace")
    if path.suffix.lower() == ".csv":
        return _csv(text, path)
    if path.suffix.lower() == ".bsdf":
        return _zemax(text, path)
    raise InputError(f"unknown BRDF data format '{path.suffix}'", file=str(path),
                     valid="a Zemax tabular .bsdf file or a .csv with columns " + ", ".join(CSV_COLUMNS))


def _rho(spec_deg: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|β − β0| for unit scatter directions (N, 3) (z = normal) about specular angles (N,); above-surface mask."""
    beta0 = np.column_stack([np.sin(np.radians(spec_deg)), np.zeros(len(spec_deg))])
    return np.linalg.norm(direction[:, :2] - beta0, axis=1), direction[:, 2] > 1e-9


def _csv(text: str, path: Path):
    rows = list(csv.reader(line for line in text.splitlines() if line.strip() and not line.startswith("#")))
    if not rows or tuple(c.strip() for c in rows[0]) != CSV_COLUMNS:
        raise InputError("the CSV header is not the expected one", file=str(path), line=1,
                         valid=",".join(CSV_COLUMNS) + " (one measurement per row)")
    try:
        data = np.array([[float(c) for c in row] for row in rows[1:]], np.float64).reshape(-1, 3)
    except ValueError as exc:
        raise InputError(f"a value is not a number ({exc})", file=str(path), valid="numbers in every column") from None
    theta_i, theta_s, f = data.T
    s = np.radians(theta_s)
    direction = np.column_stack([np.sin(s), np.zeros(len(s)), np.cos(s)])
    rho, up = _rho(theta_i, direction)
    return rho[up], f[up]


def _zemax(text: str, path: Path):
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("#")]
    header, k = {}, 0
    counted = ("SampleRotation", "AngleOfIncidence", "ScatterAzimuth", "ScatterRadial")
    while k < len(lines) and lines[k] != "DataBegin":
        key, _, value = lines[k].partition(" ")
        if key in counted:
            n = int(value.split()[0])
            values = [float(x) for x in lines[k + 1].split()]
            if len(values) != n:
                raise InputError(f"{key} announces {n} values but lists {len(values)}", file=str(path), field=key,
                                 valid=f"{n} numbers on the line after '{key}'")
            header[key] = np.array(values)
            k += 2
            continue
        header[key] = value.strip()
        k += 1
    missing = [c for c in counted if c not in header]
    if missing or k == len(lines):
        raise InputError(f"not a Zemax tabular BSDF file (missing {', '.join(missing) or 'DataBegin'})",
                         file=str(path), valid="the BSDF data interchange format: header, DataBegin, data, DataEnd")
    if header.get("ScatterType", "BRDF") != "BRDF" or header.get("SpectralContent", "Monochrome") != "Monochrome" \
            or len(header["SampleRotation"]) != 1:
        raise InputError("only isotropic monochrome BRDF data is supported", file=str(path), field="ScatterType",
                         valid="ScatterType BRDF, SpectralContent Monochrome, one SampleRotation")
    aoi, azimuth, radial = header["AngleOfIncidence"], header["ScatterAzimuth"], header["ScatterRadial"]
    body = [ln for ln in lines[k + 1:] if ln not in ("Monochrome", "DataEnd")]
    rows = [ln for ln in body if not ln.startswith("TIS")]
    if len(rows) != len(aoi) * len(azimuth):
        raise InputError(f"expected {len(aoi) * len(azimuth)} data rows (incidences × azimuths), found {len(rows)}",
                         file=str(path), field="DataBegin", valid="one row of radial values per azimuth per incidence")
    f = np.array([[float(x) for x in row.split()] for row in rows], np.float64)
    if f.shape[1] != len(radial):
        raise InputError(f"data rows hold {f.shape[1]} values, ScatterRadial lists {len(radial)}", file=str(path),
                         field="ScatterRadial", valid="one value per radial angle in every row")
    spec = np.repeat(aoi, len(azimuth) * len(radial))
    az = np.tile(np.repeat(np.radians(azimuth), len(radial)), len(aoi))
    rad = np.tile(np.radians(radial), len(aoi) * len(azimuth))
    # Directions about the specular one: azimuth 0 points from the specular direction toward the normal.
    s = np.radians(spec)
    r_hat = np.column_stack([np.sin(s), np.zeros_like(s), np.cos(s)])
    toward_normal = np.column_stack([-np.cos(s), np.zeros_like(s), np.sin(s)])
    side = np.tile([0.0, 1.0, 0.0], (len(s), 1))
    direction = (np.cos(rad)[:, None] * r_hat
                 + np.sin(rad)[:, None] * (np.cos(az)[:, None] * toward_normal + np.sin(az)[:, None] * side))
    rho, up = _rho(spec, direction)
    return rho[up], f.ravel()[up]


__all__ = ["read_brdf", "CSV_COLUMNS"]
