"""BSDF tests: the shared helpers live in bsdf_support.py next to this file."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
