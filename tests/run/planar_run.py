"""A small planar run driven from the command line, for the process-level tests of the runner.

    python planar_run.py CHECKPOINT PASSES WORKERS [--resume] [--cluster local:N | --scheduler ADDRESS]
                         [--worker-wait SECONDS] [--crash-once MARKER]

Prints one line per merged pass ("merged N") and, at the end, the accumulator's flux
series as JSON on the last line. `--crash-once` makes the worker that first computes
pass 3 die (os._exit) once (`crashing_pass.crash_once`, importable by local and Dask workers alike), to
test that a lost pass is re-run with the same result.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "integrators"))
sys.path.insert(0, str(HERE))

from planar import Collimated, Detector, Face, Lambert, PlanarScene  # noqa: E402

from lensmount.analysis.passes import Accumulator  # noqa: E402
from lensmount.run.executor import executor_for  # noqa: E402
from lensmount.integrators.estimate import film_channels  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.run.runner import RUN_PASS, PassJob, Runner, Stopping  # noqa: E402

TRACER = "planar:PlanarTracer"


def scene():
    th = math.radians(30)
    d = (math.sin(th), 0, -math.cos(th))
    return PlanarScene([Face((0, 0, 0), (0, 0, 1), (1, 0, 0), (20.0, 0), "plate", disc=True)], [Lambert(0.2)],
                       Detector(2.0, 2.0, 4, 4, 20.0), Collimated(d, (-300 * d[0], 0, 300 * -d[2]), 25.0))


def main(argv):
    checkpoint, passes, workers = Path(argv[0]), int(argv[1]), int(argv[2])
    resume = "--resume" in argv
    cluster = argv[argv.index("--cluster") + 1] if "--cluster" in argv else None
    scheduler = argv[argv.index("--scheduler") + 1] if "--scheduler" in argv else None
    wait_s = float(argv[argv.index("--worker-wait") + 1]) if "--worker-wait" in argv else 300.0
    crash = argv[argv.index("--crash-once") + 1] if "--crash-once" in argv else None
    delay = float(os.environ.get("PLANAR_PASS_DELAY", "0"))
    sc = scene()

    if crash:  # before the workers start: they inherit the variable
        os.environ["PLANAR_CRASH_MARKER"] = str(crash)

    def job(i):
        return PassJob("bidirectional", 2000, 5, i, EstimatorSettings(samples_per_pixel=16))

    acc = Accumulator.load(checkpoint)[0] if resume else Accumulator.empty((4, 4), film_channels(sc), 0.25)

    def progress(a, elapsed):
        print(f"merged {a.n}", flush=True)
        time.sleep(delay)

    executor = executor_for(workers=workers, cluster=cluster, scheduler=scheduler, worker_wait_s=wait_s,
                            say=lambda text: print(text, flush=True))
    runner = Runner(sc, job, acc, executor=executor, checkpoint=checkpoint, checkpoint_every=1, progress=progress,
                    tracer_path=TRACER, run_pass_path="crashing_pass:crash_once" if crash else RUN_PASS)
    runner.run(Stopping(max_passes=passes))
    print(json.dumps({"flux": acc.pass_flux, "n": acc.n, "terminated": runner.terminated,
                      "interrupted": runner.interrupted, "elapsed_s": acc.elapsed_s,
                      "workers_gone": runner.workers_gone}), flush=True)
    if runner.workers_gone:
        return 75
    return 143 if runner.terminated else (130 if runner.interrupted else 0)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
