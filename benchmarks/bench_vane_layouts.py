"""Line-of-sight against evenly spaced hood vanes, same count, on the reference design (issue 18).

Both mounts are the reference (examples/double-gauss-360) with `[vanes] placement` set to
"line-of-sight" (the construction's count, 12 hood vanes here) or "even" with that same
count. Printed: the stray fraction of the paper's case 2 (Lambertian 5 % everywhere, sun
7° off axis; 150 × 150 px) for each, its standard error and kernel-bias bound, the
difference with its combined error (the two standard errors in quadrature plus both bias
bounds) and its paired error (same seed), and the share of the stray light whose last
scatter was on the hood or a vane. A third run paints the line-of-sight hood and its vanes
black (absorber): the change is all the stray light that touches the hood or a hood vane at
any bounce, the most any vane layout can change.

`hood` mode puts the sun past the hood's cutoff (computed from the built layout: the steepest
angle at which a sun ray still reaches lens 1's clear aperture past the vanes), where only light
that touched the hood reaches the detector: by default at the smallest sun angle at which the
even layout leaves lit bore in the entrance aperture's sight (`check --from aperture`; below it
neither layout does), on request just past the cutoff. It
adds the example's own 3 even vanes and both layouts with black vanes, and reports per layout
the lit hood bore the entrance aperture sees and the heavy tail of the per-pass values (largest
pass / mean, skewness).

`python benchmarks/bench_vane_layouts.py [passes] [off-axis degrees]` (default 24 passes of
100 000 photons, 7°); `python benchmarks/bench_vane_layouts.py hood [passes] [degrees above
the cutoff]` (default 48 passes at the steep angle; with degrees, just past the cutoff instead);
run.py runs both with their defaults. Same seed, same numbers.
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


def scene_of(design: Path, off_axis_deg: float, black: tuple[str, ...] = ()):
    """(design, scene) of case 2 at 150 × 150 px with the sun `off_axis_deg` off the axis, the
    parts named in `black` absorbing."""
    from lensmount.loop.prepare import build, read_inputs

    d, spec = read_inputs(design, design / "scenes" / "case2-lambertian.toml")
    spec = spec.model_copy(update={"detector": spec.detector.model_copy(update={"pixels": (150, 150)}),
                                   "source": spec.source.model_copy(update={"off_axis_deg": off_axis_deg}),
                                   "assign": {**spec.assign, **{f"part:{n}": "absorber" for n in black}}})
    return d, build(d, spec).scene


def run(design: Path, passes: int, off_axis_deg: float, black: tuple[str, ...] = (), scene=None):
    """(hood vanes, stray fraction, std error, bias bound, hood + hood vanes share, per-pass stray
    fractions) of case 2 (`scene`, else `scene_of(design, off_axis_deg, black)`)."""
    from lensmount.analysis.passes import Accumulator
    from lensmount.run.executor import executor_for
    from lensmount.integrators.bidirectional import part_names
    from lensmount.run.runner import PassJob, Runner, Stopping

    scene = scene if scene is not None else scene_of(design, off_axis_deg, black)[1]
    names = part_names(scene)
    acc = Accumulator.empty((scene.detector.ny, scene.detector.nx), names, scene.detector.pixel_area)
    Runner(scene, lambda i: PassJob("bidirectional", PHOTONS, 1, i), acc,
           executor=executor_for(workers=1)).run(Stopping(max_passes=passes))
    aperture = scene.entrance_pupil_area_mm2 * scene.source.entering_fraction
    hood = hood_parts(scene)
    baffle = sum(f for n, f in zip(names, acc.part_flux) if n in hood)
    series = np.asarray(acc.pass_flux) / aperture
    return len(hood) - 1, acc.flux / aperture, acc.flux_std_error / aperture, (acc.bias_bound()[0].bound or math.inf) / aperture, \
        baffle / max(acc.flux, 1e-300), series


def hood_parts(scene) -> set[str]:
    """The hood and the vanes in it (parts starting in front of lens 1's vertex)."""
    mesh = scene.mesh
    return {t.part for k, t in enumerate(mesh.tag_table) if t.kind in ("hood", "vane")
            and mesh.vertices[mesh.triangles[mesh.tags == k].ravel(), 2].min() < 0.0}


def hood_cutoff_deg(layout, prescription) -> float:
    """The steepest sun angle at which a straight sun ray still reaches the first lens's clear
    aperture past every hood vane (the sun's centre; its 0.27° radius comes on top): the
    openings are both ends of each hood vane's edge land and surface 1's clear aperture at
    the sag of its rim (`cad.kinds.hood.steepest_sun_slope`)."""
    from lensmount.cad.kinds.hood import steepest_sun_slope
    from lensmount.optics.profiles import Profile

    s = prescription.surfaces[0]
    a = float(s.clear_semi_diameter)
    z_a = float(prescription.vertex_z[0] + Profile.of(s).sag(a * a))
    openings = [(z_a, a)] + [(t.z_front + k * t.edge_width, t.inner_radius) for p in layout.parts
                             if p.kind == "vane" and (t := p.template).z_front < z_a for k in (0, 1)]
    return math.degrees(math.atan(steepest_sun_slope(openings)))


def lit_bore_seen(design, scene, angle: float):
    """(lit hood bore mm², every lit face but vane edges mm², smallest sun angle lighting that bore
    or None) the entrance aperture sees with the sun at `angle` or beyond (`lensmount check --from
    aperture`)."""
    from lensmount.loop.sightlines import lit_walls_seen

    hs = design.mount.housing
    report = lit_walls_seen(design.prescription, scene.mesh, (hs.detector_width_mm, hs.detector_height_mm),
                            angle, "aperture")
    bore = [w for w in report.walls if w.part == "hood" and w.face == 0]  # the bore is the hood's first face
    return (sum(w.area_mm2 for w in bore), sum(w.area_mm2 for w in report.walls),
            min((w.smallest_angle_deg for w in bore), default=None))


def tails(series: np.ndarray) -> str:
    """Largest pass over the mean, and the skewness of the per-pass values (heavy tails show here)."""
    m, sd = series.mean(), series.std()
    skew = float(((series - m) ** 3).mean() / sd**3) if sd > 0 else 0.0
    return f"largest pass {series.max() / m if m > 0 else 0.0:.1f} × the mean, skewness {skew:.1f}"


def compare(rows: dict, reference: str) -> None:
    """Print each row's difference from `reference`: independent and paired (same seed) errors."""
    from lensmount.analysis.error_bar import t_factor

    _, a, sa, ba, _, pa = rows[reference]
    for label, (_, x, sx, bx, _, px) in rows.items():
        if label == reference:
            continue
        combined = math.hypot(sa, sx) + ba + bx
        # same seed: photon k draws the same numbers in both runs, so the pass-by-pass difference is
        # the difference's own series; the kernel-bias bound is common to both (same radii, same walls
        # the detector sees) and is quoted beside it, not added
        diff = px - pa
        if not diff.any():
            print(f"{label} − {reference}: the same in every pass ({x:.3e})", flush=True)
            continue
        paired = float(np.std(diff, ddof=1) / math.sqrt(len(diff)) * t_factor(len(diff)))
        share = f" ({(x - a) / a:+.1e} of it)" if a else ""
        print(f"{label} − {reference}: {x - a:+.3e}{share}; independent errors {combined:.1e} "
              f"({'resolved' if abs(x - a) > combined else 'not resolved'}); paired std error {paired:.1e} "
              f"({abs(x - a) / paired:.1f} of them: {'resolved' if abs(x - a) > 2 * paired else 'not resolved'} "
              f"at 2σ)", flush=True)


def main(argv: list[str] | None = None) -> None:
    """`[passes] [degrees]`: the sun at a fixed angle; `hood [passes] [degrees above the cutoff]`:
    the sun just past the hood's cutoff, where all the stray light has touched the hood (run.py:
    both, with their defaults)."""
    argv = list(argv or [])
    if argv[:1] == ["hood"]:
        hood_light(argv[1:])
        return
    passes = int(argv[0]) if argv else 24
    angle = float(argv[1]) if len(argv) > 1 else 7.0
    base = Path(tempfile.mkdtemp(prefix="lensmount-vanes-"))
    los, even, hood, count, _ = designs(base)
    print(f"case 2, reference design, sun {angle:g}°, 150 × 150 px, {passes} passes of {PHOTONS:,} photons")
    rows = {}
    for label, design, black in (("line-of-sight", los, ()), (f"even ({count})", even, ()),
                                 ("line-of-sight, hood black", los, tuple(hood))):
        start = time.perf_counter()
        rows[label] = run(design, passes, angle, black)
        n, s, se, bias, share, _ = rows[label]
        print(f"{label:>15}: {n} hood vanes, stray fraction {s:.6e} ± {se:.1e} (bias ≤ {bias:.1e}), "
              f"hood + vanes {100 * share:.2f} % of it  ({time.perf_counter() - start:.0f} s)", flush=True)
    compare(rows, "line-of-sight")
    shutil.rmtree(base, ignore_errors=True)
    if not argv:
        hood_light([])


def designs(base: Path):
    """(line-of-sight design, even design with its count, hood part names, count, layout)."""
    from lensmount.cad.layout import plan
    from lensmount.design.folder import load_design

    los = design_with("line-of-sight", None, base / "los")
    d = load_design(los)
    layout = plan(d.prescription, d.mount)
    hood = [p.name for p in layout.parts if p.kind == "hood" or (p.kind == "vane" and p.template.z_front < 0)]
    count = len(hood) - 1
    return los, design_with("even", count, base / "even"), hood, count, (d, layout)


def hood_light(argv: list[str]) -> None:
    """Case 2 with the sun past the hood's cutoff, where no sun ray reaches the first lens and all
    the stray light has touched the hood: at the smallest sun angle at which the even layout leaves
    lit bore in the entrance aperture's sight (`check --from aperture` on the built mesh), or
    `above` degrees past the cutoff. Line-of-sight vanes, even vanes of the same count,
    the example's own 3 even vanes, and the two layouts with their vanes black (absorber): then
    the light the bore itself sends past the vanes is what is left, with the hood's flange."""
    passes = int(argv[0]) if argv else 48
    above = float(argv[1]) if len(argv) > 1 else None
    base = Path(tempfile.mkdtemp(prefix="lensmount-vanes-"))
    los, even, hood, count, (d, layout) = designs(base)
    few = design_with("even", None, base / "even-3")
    cutoff = hood_cutoff_deg(layout, d.prescription)
    d_even, s_even = scene_of(even, cutoff)
    steep = lit_bore_seen(d_even, s_even, cutoff)[2]
    vanes = tuple(n for n in hood if n != "hood")
    print(f"case 2, reference design, {count} line-of-sight hood vanes: the hood's cutoff (no sun ray reaches "
          f"lens 1's clear aperture) is {cutoff:.2f}°; even vanes of that count leave lit bore in the entrance "
          f"aperture's sight from a sun at {steep}°; 150 × 150 px, {passes} passes of {PHOTONS:,} photons")
    # below the steep angle neither layout leaves lit bore in the aperture's sight: by default only
    # the steep angle is run, just past the cutoff on request
    for angle in (steep,) if above is None else (round(cutoff + above, 2),):
        if angle is None:
            continue
        print(f"sun at {angle:g}°:")
        rows = {}
        for label, design, black in (("line-of-sight", los, ()), (f"even ({count})", even, ()),
                                     ("line-of-sight, vanes black", los, vanes),
                                     (f"even ({count}), vanes black", even, vanes), ("even (3)", few, ())):
            start = time.perf_counter()
            design_, scene = scene_of(design, angle, black)
            seen = "" if black else "lit hood bore seen from the aperture {:.0f} mm² (all lit faces {:.0f} mm²), ".format(
                *lit_bore_seen(design_, scene, angle)[:2])
            rows[label] = run(design, passes, angle, scene=scene)
            n, s, se, bias, _, series = rows[label]
            print(f"{label:>27}: {n} hood vanes, {seen}stray fraction {s:.3e} ± {se:.1e} (bias ≤ {bias:.1e}); "
                  f"{tails(series)}  ({time.perf_counter() - start:.0f} s)", flush=True)
        compare({k: v for k, v in rows.items() if "black" not in k}, "line-of-sight")
        compare({k: v for k, v in rows.items() if "black" in k}, "line-of-sight, vanes black")
    shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main(sys.argv[1:])
