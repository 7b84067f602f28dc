"""The count of injected faults, printed at the end of a session (tests/conftest.py), and
each fault's description with its seed, so a failure names what to replay."""

from __future__ import annotations

INJECTED: list[str] = []


def record(what: str) -> None:
    """One injected fault (what, where, and the seed that chose it)."""
    INJECTED.append(what)
