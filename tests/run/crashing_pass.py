"""A pass function for `Runner(run_pass_path=...)` whose worker dies the first time anyone computes
pass 3 (os._exit, as an out-of-memory kill would), then computes passes as the runner's own does.

A module of its own, on the path every worker gets (planar_run.py's folder): a Dask worker is a
separate process that imports what a task names, so a pass function or integrator defined only in
the driver (registered in its INTEGRATORS at run time) is unknown there (KeyError on the worker).
The marker file named by $PLANAR_CRASH_MARKER records the crash; workers inherit the variable."""

from __future__ import annotations

import os
from pathlib import Path

from lensmount.run.runner import run_pass

CRASH_AT = 3


def crash_once(scene, tracer, job):
    marker = Path(os.environ["PLANAR_CRASH_MARKER"])
    if job.index == CRASH_AT and not marker.exists():
        marker.write_text(str(os.getpid()))
        os._exit(17)
    return run_pass(scene, tracer, job)
