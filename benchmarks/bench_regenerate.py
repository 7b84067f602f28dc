"""Regenerate the reference design (examples/double-gauss-360): cold and cached times.

Cold: a fresh output folder, so layout (real-ray beam envelope), checks, solids,
STEP export and tessellation all run. Cached: the same inputs again (content hash
hit: no CAD kernel). Also prints the per-step split of the cold run.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "double-gauss-360"


def main() -> None:
    from lensmount.cad.pipeline import regenerate

    with tempfile.TemporaryDirectory() as tmp:
        design = Path(tmp) / "design"
        design.mkdir()
        for f in ("lens.toml", "mount.toml"):
            shutil.copy2(EXAMPLE / f, design / f)
        marks: dict[str, float] = {}
        t0 = time.perf_counter()

        def progress(step, done, total):
            marks[step] = time.perf_counter() - t0

        m = regenerate(design, Path(tmp) / "out", progress=progress)
        cold = time.perf_counter() - t0
        t1 = time.perf_counter()
        m2 = regenerate(design, Path(tmp) / "out")
        cached = time.perf_counter() - t1
        assert m2.cached
        tri = sum(p.triangles for p in m.parts)
        print(f"parts: {len(m.parts)}, triangles: {tri}")
        prev = 0.0
        for step in ("layout", "checks", "solids", "tessellation", "export"):
            if step in marks:
                print(f"  {step:<13} {marks[step] - prev:7.2f} s")
                prev = marks[step]
        print(f"regenerate cold:   {cold:7.2f} s")
        print(f"regenerate cached: {cached:7.3f} s  (speed-up x{cold / max(cached, 1e-9):.0f})")


if __name__ == "__main__":
    main()
