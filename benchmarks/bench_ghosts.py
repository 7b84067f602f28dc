"""The ghosts channel: deterministic ghost routes vs the stochastic reflection branch, same error.

Scene: the uncoated Cooke triplet's ghost scene (examples/cooke-triplet-uncoated/scenes/ghosts-uncoated.toml:
sun 10° off axis, bare glass, black mount), forward passes of the scene's photons per pass.

Figures printed, each as seconds to 1 % relative error of the `ghosts` channel (time per pass ×
the passes' relative variance / 0.01², passes being independent):
1. photons only (`ghost_routes = false`): the stochastic branch carries the whole channel;
2. the routes alone (`ghost_routes_pass`, `ghost_rays_across` lattice points, a randomised lattice
   per pass): the two-reflection part, what replaces the photons' share of it;
3. a pass as simulate runs it (`ghost_routes = true`): photons (for four and more reflections and
   for everything else) plus the routes;
and the ratios 1 / 3 (end to end) and 1 / 2 (the two-reflection part alone).

`python benchmarks/bench_ghosts.py [passes] [design scene photons_per_pass]` (default 6 per mode on
the uncoated Cooke triplet; e.g. `6 double-gauss-360-mgf2 ghosts-mgf2.toml 200000` for the reference design).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TARGET = 0.01


def _scene(design: str, scene: str, photons: int | None):
    from lensmount.loop.prepare import prepare

    folder = ROOT / "examples" / design
    prepared = prepare(folder, folder / "scenes" / scene)
    return prepared.scene, photons or prepared.spec.run.photons


def _cost(run_pass, passes: int) -> tuple[float, float, float]:
    """(seconds per pass, mean, seconds to TARGET relative error) over `passes` timed passes."""
    values, times = [], []
    for i in range(passes):
        start = time.perf_counter()
        values.append(run_pass(i))
        times.append(time.perf_counter() - start)
    v = np.asarray(values)
    mean = float(v.mean())
    rel_var = float(v.var(ddof=1)) / mean ** 2 if mean > 0 else math.inf
    per_pass = float(np.mean(times))
    return per_pass, mean, per_pass * rel_var / TARGET ** 2


def main(passes: int = 6, design: str = "cooke-triplet-uncoated", scene_file: str = "ghosts-uncoated.toml",
         photons: int | None = None) -> dict:
    from lensmount.integrators.estimate import EnergyLedger, Film, film_channels
    from lensmount.integrators.forward import Forward
    from lensmount.integrators.ghost_routes import ghost_routes_pass, route_reflections
    from lensmount.integrators.settings import EstimatorSettings
    from lensmount.trace.tracer import Tracer

    scene, photons = _scene(design, scene_file, photons)
    print(f"{design} / {scene_file}: {photons:,} photons per pass, {passes} passes per mode", flush=True)
    tracer = Tracer(scene)
    ghosts = film_channels(scene).index("ghosts")
    settings = EstimatorSettings()

    def photons_only(i):
        return Forward(EstimatorSettings(ghost_routes=False)).run_pass(scene, tracer, i, photons, 1).part_flux[ghosts]

    def routes_only(i):
        film = Film(scene, route_reflections(scene, settings))
        ghost_routes_pass(scene, tracer, film, i, 1, settings.ghost_rays_across)
        return film.estimate(0, EnergyLedger()).part_flux[ghosts]

    def as_simulate(i):
        return Forward(settings).run_pass(scene, tracer, i, photons, 1).part_flux[ghosts]

    figures = {}
    for name, run in (("photons only", photons_only), ("routes alone", routes_only), ("simulate pass", as_simulate)):
        per_pass, mean, to_target = _cost(run, passes)
        figures[name] = to_target
        print(f"{name:>14}: {per_pass:7.2f} s/pass, ghosts flux {mean:.5g} mm², {to_target:10.1f} s to "
              f"{100 * TARGET:g} %", flush=True)
    print(f"ratio photons only / simulate pass (end to end, same error): "
          f"{figures['photons only'] / figures['simulate pass']:.0f}x")
    print(f"ratio photons only / routes alone (the two-reflection part): "
          f"{figures['photons only'] / figures['routes alone']:.0f}x")
    return figures


if __name__ == "__main__":
    args = sys.argv[1:]
    main(int(args[0]) if args else 6, *(args[1:3]), *(int(a) for a in args[3:4]))
