"""What the effects planner buys on the seed paper's case 1 (issue 15).

Two scenes on the reference double Gauss, both through `loop.prepare` (read_inputs + build) and
the planner (`integrators.plan`):

- *case 1 as written* (`scenes/case1-diaphragm-edge.toml`): only the 50 µm diaphragm edge
  scatters (`scatter = ["role:diaphragm-edge"]`), so hit points are made only there;
- *everything on*: the same file with every face keeping its mount finish (the `"*" = "absorber"`
  rule dropped: black-anodised barrel, spacers, housing, ground-glass lens rims), and
  `scatter = true`, `ghosts = { order = 2 }`, `direct = true`.

The diaphragm edge gets a channel of its own in both (its faces relabelled part
`diaphragm-edge`: the same faces, finishes and physics, only the image split finer). Each
scene runs bidirectional passes for a time budget after one warm-up pass (the learned edge
target's pilot); the figure of merit is photons per second to the same error on that channel,
1 / (seconds per photon · relative variance per photon), and the printed ratio is case 1's over
everything on's. The two means must agree within their errors (the edge channel's only extra
paths with everything on are edge scatters of light first scattered by a 5 % black face).

`python benchmarks/bench_planner.py [budget_seconds] [pixels]` (default 60 s per scene, 600 px).
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "examples" / "double-gauss-360"
CASE1 = DESIGN / "scenes" / "case1-diaphragm-edge.toml"
EDGE = "diaphragm-edge"


def split_edge(scene):
    """The scene with the diaphragm edge's faces as a part (channel) of their own."""
    from lensmount.mesh import TaggedMesh

    m = scene.mesh
    table = [replace(t, part=EDGE) if t.role == "diaphragm-edge" else t for t in m.tag_table]
    return replace(scene, mesh=TaggedMesh(m.vertices, m.triangles, m.tags, table))


def case1_scenes(pixels: int | None = None):
    """(case 1 as written, everything on): planned Scenes with the edge split out."""
    from lensmount.design.scene import EffectsSpec, GhostsSpec
    from lensmount.integrators.plan import plan
    from lensmount.loop.prepare import build, read_inputs

    design, spec = read_inputs(DESIGN, CASE1)
    if pixels:
        spec = spec.model_copy(update={"detector": spec.detector.model_copy(update={"pixels": (pixels, pixels)})})
    everything = spec.model_copy(update={
        "effects": EffectsSpec(scatter=True, ghosts=GhostsSpec(order=2), direct=True),
        "assign": {k: v for k, v in spec.assign.items() if k != "*"}})
    geometry = Path(tempfile.gettempdir()) / "lensmount-bench-geometry"
    return tuple(plan(split_edge(build(design, s, geometry).scene)).scene for s in (spec, everything))


class Efficiency(NamedTuple):
    mean: float  # edge channel flux, mm²
    std_error: float
    passes: int
    photons: int
    seconds: float  # timed passes only
    hit_point_tags: int  # faces where the plan lets hit points be made

    @property
    def merit(self) -> float:
        """Photons per second to the same error: 1 / (s per photon · relative variance per photon)."""
        rel_var = (self.std_error / self.mean) ** 2 * self.photons  # per photon
        return self.photons / self.seconds / rel_var if rel_var > 0 else math.inf


def measure(scene, budget_s: float, photons: int, seed: int = 1, min_passes: int = 4) -> Efficiency:
    """Bidirectional passes of `scene` for budget_s (after a warm-up pass), the edge channel's figures."""
    from lensmount.integrators.bidirectional import Bidirectional, gather_cores
    from lensmount.integrators.walk import scattering_tags
    from lensmount.trace.tracer import Tracer

    tracer = Tracer(scene)
    method = Bidirectional()
    k = method.channels(scene).index(EDGE)
    method.run_pass(scene, tracer, 0, photons, seed)  # warm-up: the learned edge target's pilot, caches
    flux, start = [], time.perf_counter()
    while len(flux) < min_passes or time.perf_counter() - start < budget_s:
        flux.append(float(method.run_pass(scene, tracer, len(flux) + 1, photons, seed).part_flux[k]))
    seconds = time.perf_counter() - start
    broad = np.isfinite(gather_cores(scene.bsdf_of_tag))  # the faces where hit points are made
    f = np.asarray(flux)
    return Efficiency(float(f.mean()), float(f.std(ddof=1) / math.sqrt(len(f))), len(f), photons * len(f), seconds,
                      int((broad & scattering_tags(scene)).sum()))


def main() -> None:
    args = [a for a in sys.argv[1:] if a.replace(".", "").isdigit()]
    budget = float(args[0]) if args else 60.0
    pixels = int(args[1]) if len(args) > 1 else 600
    photons = 100_000
    t0 = time.perf_counter()
    case1, everything = case1_scenes(pixels)
    print(f"case 1 vs everything on, reference design, {pixels} × {pixels} px, {photons:,} photons per pass, "
          f"{budget:g} s per scene (setup {time.perf_counter() - t0:.1f} s)")
    rows = {}
    for name, scene, seed in (("case 1 as written", case1, 1), ("everything on", everything, 2)):
        e = rows[name] = measure(scene, budget, photons, seed)  # independent seeds: an honest comparison
        print(f"  {name:18s}: edge channel {e.mean:.4g} ± {e.std_error:.2g} mm² ({e.passes} passes, "
              f"{e.seconds:.1f} s, {e.seconds / e.passes:.2f} s/pass), hit points on {e.hit_point_tags} faces, "
              f"{e.merit:.3g} photons/s to the same error")
    a, b = rows["case 1 as written"], rows["everything on"]
    print(f"  ratio (case 1 / everything on), photons per second to the same error = {a.merit / b.merit:.2f}")
    from lensmount.analysis.error_bar import t_factor

    z = (a.mean - b.mean) / math.hypot(a.std_error * t_factor(a.passes), b.std_error * t_factor(b.passes))
    print(f"  edge channels differ by {a.mean - b.mean:+.3g} mm² = {z:+.2f} σ (errors widened by Student's t)")


if __name__ == "__main__":
    main()
