"""Under pytest-xdist the workers already share the cores (Makefile: one per core), so each walks
rays on one core, as `simulate`'s worker processes do (`lens_kernel.one_core_per_process`); a
test that is about the threaded walk switches it on itself."""

import os

from lensmount.trace import lens_kernel

if os.environ.get("PYTEST_XDIST_WORKER"):
    lens_kernel.one_core_per_process()
