"""lensmount.run — running passes and keeping what they produced.

    run.runner    Runner, PassJob, run_pass: passes on an executor until a stop rule holds
    run.executor  local worker processes or a Dask cluster
    run.results   EXR, PNG, summary.json and report.html of one run
    run.report    the self-contained report.html pages
    run.store     runs.sqlite, the results store

Sits between the loop (which decides what to run) and the statistics of `lensmount.analysis`.
"""
