"""Under pytest-xdist the workers already share the cores (Makefile: one per core), so each walks
rays on one core, as `simulate`'s worker processes do (`lens_kernel.one_core_per_process`); a
test that is about the threaded walk switches it on itself."""

import os

from lensmount.trace import lens_kernel

if os.environ.get("PYTEST_XDIST_WORKER"):
    lens_kernel.one_core_per_process()


_INJECTED = [0]  # faults injected by tests/faults (each test reports its count as a user property)


def pytest_runtest_logreport(report):
    if report.when == "teardown":
        _INJECTED[0] += sum(n for key, n in report.user_properties if key == "injected faults")


def pytest_terminal_summary(terminalreporter):
    if _INJECTED[0]:
        terminalreporter.write_line(f"injected faults: {_INJECTED[0]}")
