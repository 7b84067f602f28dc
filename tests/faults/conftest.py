"""The fault-injection suite: every case injects faults and records them (fault_log.record);
each test's count travels in its report (also to the pytest-xdist controller), and tests/conftest.py
prints the total at the end of the session ("injected faults: N")."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fault_log import INJECTED  # noqa: E402


@pytest.fixture(autouse=True)
def _count_injected(request):
    before = len(INJECTED)
    yield
    request.node.user_properties.append(("injected faults", len(INJECTED) - before))
