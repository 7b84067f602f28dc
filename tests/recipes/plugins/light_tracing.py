"""An integrator added the way docs/architecture.md says ("Where to add an integrator"): this file, which
registers itself in `INTEGRATORS`, and its line in the plug-in package's entry points; nothing of lensmount
touched. `lensmount simulate --method light-tracing` then runs it, in every worker.

Light tracing at its plainest: the shared photon walk with every photon that reaches the detector put on
the film where it lands, ghosts included (no deterministic ghost routes). On a scene whose ghosts are off
it is the `forward` integrator, photon for photon.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from lensmount.integrators.estimate import EnergyLedger, Film, PassEstimate, film_channels, phase_clock, phase_times
from lensmount.integrators.registry import INTEGRATORS
from lensmount.integrators.settings import EstimatorSettings
from lensmount.integrators.walk import emit_photons, photon_walk


class LightTracingParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    batch: int = Field(200_000, ge=1_000)  # photons walked at once: bounds memory, not the result


class LightTracing:
    name = "light-tracing"
    purpose = "forward"  # the forward integrator's random streams: the same photons

    def __init__(self, params: LightTracingParams, settings: EstimatorSettings):
        self.batch, self.settings = params.batch, settings

    def channels(self, scene) -> list[str]:
        return film_channels(scene)

    def run_pass(self, scene, tracer, pass_index: int, photons: int, seed: int,
                 radius_scale: float | None = None) -> PassEstimate:
        film, ledger, first, clock = Film(scene, ()), EnergyLedger(), int(pass_index) * int(photons), phase_clock()
        for start in range(0, photons, self.batch):
            rays = emit_photons(scene, seed, self.purpose, first + start, min(self.batch, photons - start), photons)
            for _ in photon_walk(scene, tracer, rays, seed, self.purpose, self.settings, film, ledger):
                pass
        return film.estimate(photons, ledger, phase_times(walk=phase_clock() - clock))


@INTEGRATORS.register("light-tracing", LightTracingParams)
def make_light_tracing(params: LightTracingParams, settings: EstimatorSettings) -> LightTracing:
    """Light tracing: every photon on the film where it lands, ghosts by photons too."""
    return LightTracing(params, settings)
