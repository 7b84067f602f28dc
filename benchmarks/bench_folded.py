"""Folded, tilted and decentred .zmx files: lensmount's chief ray and EFLs along the folded axis against rayoptics.

    PYTHONPATH=src python benchmarks/bench_folded.py [FILE.zmx ...]

rayoptics (not a test dependency) reads each file itself and traces, with its own real-ray tracer,
the rays lensmount launches: the chief ray of the on-axis field and the rays offset by ±h beside it, taken after the last surface
onto lensmount's image plane.
Printed per file: the image-plane vertex (assembly frame) from both, the chief ray's point on the
image plane in the image frame, and the EFLs (x and y) from the same small-angle derivative on
rayoptics's rays; and rayoptics's own paraxial EFL, which unfolds the system and ignores tilts (so it
differs on a tilted mirror, where the real focal lengths are astigmatic). rayoptics writes its reader's
log, zmx_read_lens.log, into the working directory: run it from a scratch one.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from lensmount.optics.folded import folded_axis
from lensmount.optics.io.zemax import read_zmx

CORPUS = Path(__file__).resolve().parent.parent / "tests" / "optics" / "corpus" / "folded"
H = 1e-6


def rayoptics_axis(path: Path, launch, direction, h: float, image):
    from rayoptics.environment import open_model  # lazy: rayoptics is a benchmark-only reference
    from rayoptics.raytr.trace import trace

    opm = open_model(str(path))
    sm = opm["seq_model"]
    wvl = opm["optical_spec"]["wvls"].central_wvl
    gap = sm.gaps[0].thi
    d = np.array(direction)
    offsets = [np.zeros(3), [h, 0, 0], [-h, 0, 0], [0, h, 0], [0, -h, 0]]
    ends = []
    for off in offsets:   # five rays: a reference script, not the product
        start = np.array([launch[0], launch[1], 0.0]) + off - d * gap / d[2]
        ray, _, _ = trace(sm, start, d, wvl)
        # after the last surface, in the assembly frame, onto lensmount's image plane: rayoptics does
        # not read an image surface's own tilt (SCBD), so its own image plane may lie along the beam
        rot, trans = sm.gbl_tfrms[-2]
        q, e = rot @ np.array(ray[-2][0]) + trans, rot @ np.array(ray[-2][1])
        q, e = image.to_local(q[None, :], e[None, :])
        q, e = q[0], e[0]
        ends.append((q - q[2] / e[2] * e, e))
    point, chief = ends[0]
    ex = np.array([1.0, 0, 0]) - chief[0] * chief
    ey = np.array([0, 1.0, 0]) - chief[1] * chief
    ex, ey = ex / np.linalg.norm(ex), ey / np.linalg.norm(ey)
    u = np.array([[e @ ex / (e @ chief), e @ ey / (e @ chief)] for _, e in ends])
    efl_x, efl_y = -2 * h / (u[1, 0] - u[2, 0]), -2 * h / (u[3, 1] - u[4, 1])
    image_origin = sm.gbl_tfrms[-1][1]
    return point[:2], efl_x, efl_y, image_origin, opm["analysis_results"]["parax_data"].fod.efl


def main(files) -> None:
    for path in files:
        p = read_zmx(path)
        a = folded_axis(p)
        scale = max(1.0, float(np.max(np.abs([f.origin for f in p.frames])))) if p.frames else 1.0
        point, ex, ey, origin, parax = rayoptics_axis(Path(path), a.launch, a.direction, H * scale, p.frames[-1])
        ours = np.array(p.frames[-1].origin) if p.frames else np.array([0, 0, p.image_z])
        print(f"{Path(path).name}")
        print(f"  image vertex    lensmount {np.round(ours, 9)}  rayoptics {np.round(origin, 9)}  "
              f"|diff| {np.linalg.norm(ours - origin):.2e} mm")
        print(f"  chief on image  lensmount {np.round(a.image_local, 9)}  rayoptics {np.round(point, 9)}  "
              f"|diff| {np.linalg.norm(np.array(a.image_local) - point):.2e} mm")
        print(f"  EFL x           lensmount {a.efl_x:.9f}  rayoptics rays {ex:.9f}  rel {abs(a.efl_x / ex - 1):.1e}")
        print(f"  EFL y           lensmount {a.efl_y:.9f}  rayoptics rays {ey:.9f}  rel {abs(a.efl_y / ey - 1):.1e}"
              f"   (rayoptics paraxial, unfolded: {parax:.9f})")


if __name__ == "__main__":
    # the folded corpus but pyrate's file, which rayoptics's reader does not parse (UTF-16 with its own glass names)
    main(sys.argv[1:] or [p for p in sorted(CORPUS.glob("*.zmx")) if not p.name.startswith("pyrate")])
