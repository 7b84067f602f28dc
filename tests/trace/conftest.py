"""Make `tests.trace.geometry` importable however pytest is started (importlib mode adds nothing to sys.path)."""

import sys
from pathlib import Path

ROOT = str(Path(__file__).resolve().parents[2])
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
