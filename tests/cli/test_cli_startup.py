"""`lensmount --help` starts without the heavy packages: the CAD kernel, the mesh and plotting libraries
and dask are imported where a command needs them (docs/architecture.md, "Imports")."""

from __future__ import annotations

import subprocess
import sys

# What --help must not load (each costs from a fraction of a second to several seconds at start-up)
HEAVY = ("OCP", "build123d", "cadquery", "matplotlib", "embreex", "trimesh", "ezdxf", "dask", "distributed",
         "playwright", "pandas", "scipy.stats")

SCRIPT = """
import sys
sys.argv = ["lensmount", "--help"]
from lensmount.cli import main
try:
    main()
except SystemExit:
    pass
print("LOADED " + " ".join(sorted(sys.modules)))
"""


def test_help_loads_no_heavy_package():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True)
    assert "regenerate" in done.stdout and "simulate" in done.stdout  # the help itself was printed
    loaded = done.stdout.rsplit("LOADED ", 1)[1].split()
    heavy = sorted(m for m in loaded if any(m == h or m.startswith(h + ".") for h in HEAVY))
    assert heavy == [], f"lensmount --help imported {heavy[:10]}: import them inside the function that needs them"
