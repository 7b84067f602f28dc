"""Line-of-sight against evenly spaced hood vanes, same count, on the reference design (issue 18).

Both mounts are the reference (examples/double-gauss-360) with `[vanes] placement` set to
"line-of-sight" (the construction's count, 21 hood vanes here) or "even" with that same
count. Printed: the stray fraction of the paper's case 2 (Lambertian 5 % everywhere, sun
7° off axis; 150 × 150 px) for each, its standard error and kernel-bias bound, the
difference with its combined error (the two standard errors in quadrature plus both bias
bounds), and the share of the stray light whose last scatter was on the hood or a vane.
A third run paints the line-of-sight hood and its vanes black (absorber): the change is
all the stray light that touches the hood or a hood vane at any bounce, the most any vane
layout can change.

`python benchmarks/bench_vane_layouts.py [passes] [off-axis degrees]` (default 24 passes of
100 000 photons, 7°). Same seed, same numbers.
"""

from __future__ import annotations

import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "examples" / "double-gauss-360"
PHOTONS = 100_000


def design_with(placement: str, count: int | None, folder: Path) -> Path:
    """A copy of the reference design whose vanes are placed by `placement` (`count` for even)."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy2(DESIGN / "lens.toml", folder / "lens.toml")
    shutil.copytree(DESIGN / "scenes", folder / "scenes", dirs_exist_ok=True)
    text = (DESIGN / "mount.toml").read_text().replace('placement = "even"', f'placement = "{placement}"')
    if count is not None:
        text = text.replace("count = 3 ", f"count = {count} ")
    (folder / "mount.toml").write_text(text)
    return folder


def run(design: Path, passes: int, off_axis_deg: float, black: tuple[str, ...] = ()):
    """(hood vanes, stray fraction, std error, bias bound, hood + hood vanes share) of case 2, the
    parts named in `black` absorbing."""
    from lensmount.analysis.passes import Accumulator
    from lensmount.executor import executor_for
    from lensmount.integrators.bidirectional import part_names
    from lensmount.loop.prepare import build, read_inputs
    from lensmount.runner import PassJob, Runner, Stopping

    d, spec = read_inputs(design, design / "scenes" / "case2-lambertian.toml")
    spec = spec.model_copy(update={"detector": spec.detector.model_copy(update={"pixels": (150, 150)}),
                                   "source": spec.source.model_copy(update={"off_axis_deg": off_axis_deg}),
                                   "assign": {**spec.assign, **{f"part:{n}": "absorber" for n in black}}})
    scene = build(d, spec).scene
    names = part_names(scene)
    acc = Accumulator.empty((scene.detector.ny, scene.detector.nx), names, scene.detector.pixel_area)
    Runner(scene, lambda i: PassJob("bidirectional", PHOTONS, 1, i), acc,
           executor=executor_for(workers=1)).run(Stopping(max_passes=passes))
    aperture = scene.entrance_pupil_area_mm2 * scene.source.entering_fraction
    hood = hood_parts(scene)
    baffle = sum(f for n, f in zip(names, acc.part_flux) if n in hood)
    series = np.asarray(acc.pass_flux) / aperture
    return len(hood) - 1, acc.flux / aperture, acc.flux_std_error / aperture, acc.bias_bound()[0] / aperture, \
        baffle / max(acc.flux, 1e-300), series


def hood_parts(scene) -> set[str]:
    """The hood and the vanes in it (parts starting in front of lens 1's vertex)."""
    mesh = scene.mesh
    return {t.part for k, t in enumerate(mesh.tag_table) if t.kind in ("hood", "vane")
            and mesh.vertices[mesh.triangles[mesh.tags == k].ravel(), 2].min() < 0.0}


def main() -> None:
    from lensmount.analysis.passes import t_factor
    from lensmount.cad.layout import plan
    from lensmount.design.folder import load_design

    passes = int(sys.argv[1]) if len(sys.argv) > 1 else 24
    angle = float(sys.argv[2]) if len(sys.argv) > 2 else 7.0
    base = Path(tempfile.mkdtemp(prefix="lensmount-vanes-"))
    los = design_with("line-of-sight", None, base / "los")
    d = load_design(los)
    layout = plan(d.prescription, d.mount)
    hood = [p.name for p in layout.parts if p.kind == "hood" or (p.kind == "vane" and p.template.z_front < 0)]
    count = len(hood) - 1
    even = design_with("even", count, base / "even")
    print(f"case 2, reference design, sun {angle:g}°, 150 × 150 px, {passes} passes of {PHOTONS:,} photons")
    rows = {}
    for label, design, black in (("line-of-sight", los, ()), (f"even ({count})", even, ()),
                                 ("line-of-sight, hood black", los, tuple(hood))):
        start = time.perf_counter()
        rows[label] = run(design, passes, angle, black)
        n, s, se, bias, share, _ = rows[label]
        print(f"{label:>15}: {n} hood vanes, stray fraction {s:.6e} ± {se:.1e} (bias ≤ {bias:.1e}), "
              f"hood + vanes {100 * share:.2f} % of it  ({time.perf_counter() - start:.0f} s)", flush=True)
    (_, a, sa, ba, _, pa), (_, b, sb, bb, _, pb), (_, c, sc, bc, _, pc) = rows.values()
    for what, x, sx, bx, px in (("even − line-of-sight", b, sb, bb, pb), ("hood black − line-of-sight", c, sc, bc, pc)):
        combined = math.hypot(sa, sx) + ba + bx
        # same seed: photon k draws the same numbers in both runs, so the pass-by-pass difference is
        # the difference's own series; the kernel-bias bound is common to both (same radii, same walls
        # the detector sees) and is quoted beside it, not added
        diff = px - pa
        paired = float(np.std(diff, ddof=1) / math.sqrt(len(diff)) * t_factor(len(diff)))
        print(f"{what}: {x - a:+.3e} ({(x - a) / a:+.1e} of it); independent errors {combined:.1e} "
              f"({'resolved' if abs(x - a) > combined else 'not resolved'}); paired std error {paired:.1e} "
              f"({'resolved' if abs(x - a) > 2 * paired else 'not resolved'} at 2σ)")
    shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main()
