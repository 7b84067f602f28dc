"""Forward light tracing: the unbiased, slow reference the bidirectional estimator is checked against.

One pass = the shared photon walk (`walk.photon_walk`) with every photon that reaches the
detector deposited into the film: Φ / A_pixel into its pixel (E/E_sun), in the channel of
the part where it last scattered (`direct` / `ghosts` for unscattered light when the scene
turns those effects on). Nothing is gathered.

Photon k of pass i is photon i·N + k of the run (N photons per pass), and all its random
numbers are keyed by that index: the mean image of 4 passes of 100 000 photons equals that
of 2 passes of 200 000, and the internal batch size changes nothing.
"""

from __future__ import annotations

import math

from lensmount.integrators.estimate import EnergyLedger, Film, PassEstimate, film_channels, phase_clock, phase_times
from lensmount.integrators.ghost_routes import ghost_routes_pass, route_reflections
from lensmount.integrators.registry import INTEGRATORS, NoParams
from lensmount.integrators.settings import EstimatorSettings
from lensmount.integrators.walk import emit_photons, gain_bound, photon_walk

BATCH = 200_000  # photons per batch: bounds memory, not the result (numbers are keyed per photon)


class Forward:
    """Forward light tracing (see the module docstring); the `Integrator` contract: `channels(scene)` and
    `run_pass(scene, tracer, pass_index, photons, seed, radius_scale=None)`."""

    name = "forward"
    purpose = "forward"

    def __init__(self, settings: EstimatorSettings | None = None, *, batch: int = BATCH):
        self.settings = settings or EstimatorSettings()
        self.batch = int(batch)

    def channels(self, scene) -> list[str]:
        return film_channels(scene)

    def run_pass(self, scene, tracer, pass_index: int, photons: int, seed: int,
                 radius_scale: float | None = None) -> PassEstimate:
        """One independent pass of N = `photons` photons (radius_scale: unused, nothing is gathered)."""
        by_routes = route_reflections(scene, self.settings)
        film, ledger = Film(scene, by_routes), EnergyLedger()
        first = int(pass_index) * int(photons)
        clock = phase_clock()
        heaviest = 0.0  # the largest emitted photon flux: a term is at most this × gain_bound
        for start in range(0, photons, self.batch):
            n = min(self.batch, photons - start)
            rays = emit_photons(scene, seed, self.purpose, first + start, n, photons)
            heaviest = max(heaviest, float(rays.weight.max(initial=0.0)))
            for _ in photon_walk(scene, tracer, rays, seed, self.purpose, self.settings, film, ledger):
                pass
        times = {"walk": phase_clock() - clock}
        # the deterministic ghost routes' rays carry fluxes of their own, which no photon bounds
        bound = heaviest * gain_bound(scene, self.settings) if not by_routes else math.inf
        if by_routes:
            clock = phase_clock()
            ghost_routes_pass(scene, tracer, film, pass_index, seed, self.settings.ghost_rays_across)
            times["ghost_routes"] = phase_clock() - clock
        return film.estimate(photons, ledger, phase_times(**times), term_bound=bound)


@INTEGRATORS.register("forward", NoParams)
def make_forward(params: NoParams, settings: EstimatorSettings) -> Forward:
    """Forward light tracing: every photon that reaches the detector is counted where it lands."""
    return Forward(settings)


def forward_pass(scene, tracer, n_photons: int, seed: int, pass_index: int, *, batch: int = BATCH,
                 **settings) -> PassEstimate:
    """`Forward(EstimatorSettings(**settings)).run_pass(...)` (scripts and tests)."""
    return Forward(EstimatorSettings(**settings), batch=batch).run_pass(scene, tracer, pass_index, n_photons, seed)


__all__ = ["Forward", "make_forward", "forward_pass", "BATCH"]
