"""The integrators by name: what `simulate --method` chooses.

Every integrator has the same interface, `Integrator`: made from the run's `EstimatorSettings`, it
names the film channels a pass of a scene fills, and computes one complete, independent pass.
Adding one is a module in this folder with its class and one entry in `INTEGRATORS`
(docs/architecture.md, "Where to add an integrator").
"""

from __future__ import annotations

from typing import Protocol

from lensmount.errors import InputError
from lensmount.integrators.bidirectional import Bidirectional
from lensmount.integrators.estimate import PassEstimate
from lensmount.integrators.forward import Forward
from lensmount.integrators.settings import EstimatorSettings
from lensmount.scene.scene import Scene


class Integrator(Protocol):
    """One estimator of the detector's irradiance, pass by pass.

    run_pass(scene, tracer, pass_index, photons, seed, radius_scale=None): photon k of pass i is
    photon i·photons + k of the run, so a pass is the same in any worker; radius_scale None
    follows the settings' schedule (integrators without a gather radius ignore it).

    run_pass = photon_pass(scene, tracer, view_pass(scene, tracer, pass_index, seed, radius_scale),
    pass_index, photons, seed): `view_pass` is the part of a pass that does not depend on the source
    (bidirectional: the view map; None for an integrator without one), so a sweep over sources
    (`loop.pst`) computes it once per pass for all of them; `photon_pass` takes a scene that differs
    from the view's only in its source.
    """

    name: str

    def __init__(self, settings: EstimatorSettings | None = None) -> None: ...

    def channels(self, scene: Scene) -> list[str]: ...

    def run_pass(self, scene: Scene, tracer, pass_index: int, photons: int, seed: int,
                 radius_scale: float | None = None) -> PassEstimate: ...

    def view_pass(self, scene: Scene, tracer, pass_index: int, seed: int, radius_scale: float | None = None): ...

    def photon_pass(self, scene: Scene, tracer, view, pass_index: int, photons: int, seed: int) -> PassEstimate: ...


INTEGRATORS: dict[str, type[Integrator]] = {"bidirectional": Bidirectional, "forward": Forward}


def check_method(method: str, field: str = "--method") -> None:
    """Refuse a method no integrator answers to."""
    if method not in INTEGRATORS:
        raise InputError(f"unknown method '{method}'", field=field, valid=" | ".join(INTEGRATORS))


__all__ = ["Integrator", "INTEGRATORS", "check_method"]
