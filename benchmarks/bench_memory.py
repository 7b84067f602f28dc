"""Peak resident memory of a large-detector run: case 1 of the seed paper at 2400 × 2400 pixels.

The run goes through `lensmount.loop.simulate` as `lensmount simulate` does (2 local worker
processes, a few passes, no store record). Printed:

- the peak of the summed resident memory of the driver and all its workers, sampled every
  0.1 s with psutil (what the machine must hold at once; the issue's target is < 4 GB);
- the kernel's own peaks (`getrusage` ru_maxrss): the driver's, and the largest worker's —
  driver + workers × largest worker bounds the sampled figure from above.

`python benchmarks/bench_memory.py [pixels] [passes]` (default 2400 and 2 passes).
"""

from __future__ import annotations

import resource
import sys
import tempfile
import threading
import time
import tomllib
from pathlib import Path

import psutil
import tomli_w

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "examples" / "double-gauss-360"
WORKERS = 2
GB = 1024**3


class PeakRss:
    """Samples the summed RSS of this process and its descendants in a background thread."""

    def __init__(self, every_s: float = 0.1):
        self.every_s, self.peak, self._stop = every_s, 0, threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self) -> None:
        me = psutil.Process()
        while not self._stop.is_set():
            total = 0
            for p in [me, *me.children(recursive=True)]:
                try:
                    total += p.memory_info().rss
                except psutil.Error:  # a worker that just exited
                    pass
            self.peak = max(self.peak, total)
            self._stop.wait(self.every_s)

    def __enter__(self) -> "PeakRss":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def main() -> None:
    from lensmount.loop.simulate import SimulateOptions, simulate

    args = [a for a in sys.argv[1:] if a.isdigit()]
    pixels = int(args[0]) if args else 2400
    passes = int(args[1]) if len(args) > 1 else 2
    scene_path = DESIGN / "scenes" / "case1-diaphragm-edge.toml"
    data = tomllib.loads(scene_path.read_text())
    data["detector"]["pixels"] = [pixels, pixels]
    with tempfile.TemporaryDirectory(prefix="lensmount-bench-memory-") as tmp:
        scene = Path(tmp) / "case1-large.toml"
        scene.write_text(tomli_w.dumps(data))
        options = SimulateOptions(design=DESIGN, scene=scene, out=Path(tmp) / "out", passes=passes, workers=WORKERS,
                                  geometry=Path(tempfile.gettempdir()) / "lensmount-bench-geometry", record=False)
        start = time.perf_counter()
        with PeakRss() as sampled:
            result = simulate(options)
        seconds = time.perf_counter() - start
    driver = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux reports KiB
    worker = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    print(f"case 1, {pixels} × {pixels} px, {result.summary['photons']:,} photons in {passes} passes on "
          f"{WORKERS} workers, {seconds:.0f} s")
    print(f"  peak resident memory, all processes (sampled every 0.1 s): {sampled.peak / GB:.2f} GB "
          f"(target < 4 GB: {'met' if sampled.peak < 4 * GB else 'NOT met'})")
    print(f"  kernel peaks: driver {driver / GB:.2f} GB, largest worker {worker / GB:.2f} GB "
          f"(bound driver + {WORKERS} × worker = {(driver + WORKERS * worker) / GB:.2f} GB)")


if __name__ == "__main__":
    main()
