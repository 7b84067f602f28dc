"""Write src/lensmount/optics/legacy_glasses.csv from the refractiveindex.info database (CC0).

The glasses lens files name that the built-in catalogues (opticalglass) lack: Schott's technical
glasses (B 270, D 263 T eco), Schott's obsolete LF7, the LZOS catalogue, and the Schott optical glasses
the database keeps that the built-in Schott catalogue has dropped (N-SK15, N-FK51, ...: Zemax's SCHOTT
catalogue still carries them, and lens files name them). n_d and V_d are
computed from the database's data (tabulated n, or its formulas 1 and 2, Sellmeier) at the d, F and C
lines; the import uses them as a model glass and says so.

    python tools/legacy_glasses.py /path/to/refractiveindex.info-database COMMIT
"""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

FOLDERS = {"database/data/specs/schott/misc": "Schott", "database/data/specs/schott/obsolete": "Schott (obsolete)",
           "database/data/specs/lzos/optical": "LZOS", "database/data/specs/schott/optical": "Schott (dropped)"}
DROPPED_ONLY = "database/data/specs/schott/optical"   # only the glasses the built-in Schott catalogue lacks
ALIASES = {"B270": "B 270", "D263TECO": "D263T D263 D263T_ECO D263TE"}
D, F, C = 0.5875618, 0.4861327, 0.6562725


def index(data: dict, wl: float) -> float:
    for block in data["DATA"]:
        kind = block["type"]
        if kind == "tabulated n" or kind == "tabulated nk":
            rows = np.array([[float(x) for x in r.split()[:2]] for r in block["data"].strip().splitlines()])
            rows = rows[np.argsort(rows[:, 0])]
            if not rows[0, 0] - 1e-4 <= wl <= rows[-1, 0] + 1e-4:  # the lines to 0.1 nm
                raise ValueError("the table does not reach the wavelength")
            return float(np.interp(wl, rows[:, 0], rows[:, 1]))
        if kind == "formula 1":  # Sellmeier with the C terms given as wavelengths
            c = [float(x) for x in block["coefficients"].split()]
            l2 = wl * wl
            return float(np.sqrt(1.0 + c[0] + sum(b * l2 / (l2 - cc * cc) for b, cc in zip(c[1::2], c[2::2]))))
        if kind == "formula 2":
            c = [float(x) for x in block["coefficients"].split()]
            l2 = wl * wl
            return float(np.sqrt(1.0 + c[0] + sum(b * l2 / (l2 - cc) for b, cc in zip(c[1::2], c[2::2]))))
    raise ValueError("no index data")


def main(repo: str, commit: str) -> None:
    from opticalglass import glassfactory

    built_in = {str(g).strip().upper() for g in glassfactory.get_glass_catalog("Schott").get_glass_names()}
    rows = []
    for folder, maker in FOLDERS.items():
        names = subprocess.run(["git", "--git-dir", repo, "ls-tree", "--name-only", commit, folder + "/"],
                               capture_output=True, text=True, check=True).stdout.split()
        for path in names:
            if folder == DROPPED_ONLY and Path(path).stem.upper() in built_in:
                continue
            text = subprocess.run(["git", "--git-dir", repo, "show", f"{commit}:{path}"],
                                  capture_output=True, text=True, check=True).stdout
            data = yaml.safe_load(text)
            try:
                nd, nf, nc = index(data, D), index(data, F), index(data, C)
            except ValueError as exc:
                print(f"{path}: left out ({exc})")
                continue
            name = Path(path).stem
            rows.append((name, ALIASES.get(name, ""), maker, f"{nd:.6f}", f"{(nd - 1) / (nf - nc):.3f}",
                         f"refractiveindex.info-database {path} @ {commit[:12]} (CC0)"))
    out = Path(__file__).resolve().parents[1] / "src/lensmount/optics/legacy_glasses.csv"
    with out.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(("name", "aliases", "maker", "n_d", "V_d", "source"))
        w.writerows(sorted(rows, key=lambda r: (r[0], list(FOLDERS.values()).index(r[2]))))  # Schott's first


if __name__ == "__main__":
    main(*sys.argv[1:3])
