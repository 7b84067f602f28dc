"""The fault-injection suite (issue 27): every case injects one fault and records it; the total is
printed at the end of the session ("injected faults: N")."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fault_log import INJECTED  # noqa: E402


def pytest_terminal_summary(terminalreporter):
    if INJECTED:
        terminalreporter.write_line(f"injected faults: {len(INJECTED)}")
