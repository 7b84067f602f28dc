"""The integrators by name: what `simulate --method` chooses, and what every integrator does.

An integrator is a plug-in: a module of this folder (forward.py, bidirectional.py) or of a user's package
(entry point `lensmount.plugins`, `lensmount.registry`) with its parameter model, registering a factory
`(params, settings) -> Integrator` in `INTEGRATORS` (docs/architecture.md, "Where to add an integrator").
The run's `EstimatorSettings` are the walk's knobs, shared by every integrator; a plug-in's own
parameters, if it has any, are its model's.
"""

from __future__ import annotations

from typing import Protocol, TypeVar, runtime_checkable

from pydantic import BaseModel, ConfigDict

from lensmount.integrators.estimate import PassEstimate
from lensmount.integrators.settings import EstimatorSettings
from lensmount.registry import Registry
from lensmount.scene.scene import Scene
from lensmount.trace.tracer import Tracer

View = TypeVar("View")


class Integrator(Protocol):
    """One estimator of the detector's irradiance, pass by pass.

    channels(scene): the film channels a pass of `scene` fills.
    run_pass(scene, tracer, pass_index, photons, seed, radius_scale=None): one complete, independent pass;
    photon k of pass i is photon i·photons + k of the run, so a pass is the same in any worker;
    radius_scale None follows the settings' schedule (integrators without a gather radius ignore it).
    """

    name: str

    def channels(self, scene: Scene) -> list[str]: ...

    def run_pass(self, scene: Scene, tracer: Tracer, pass_index: int, photons: int, seed: int,
                 radius_scale: float | None = None) -> PassEstimate: ...


@runtime_checkable
class SourceIndependentView(Protocol[View]):
    """An integrator whose pass splits into a part that does not depend on the source and the rest:

    run_pass = photon_pass(scene, tracer, view_pass(scene, tracer, pass_index, seed), pass_index, photons, seed),
    `photon_pass` taking a scene that differs from the view's only in its source. A sweep over sources
    (`loop.pst`) computes the view once per pass for all of them (the bidirectional's view map); an
    integrator without the split runs each source's whole pass."""

    def view_pass(self, scene: Scene, tracer: Tracer, pass_index: int, seed: int,
                  radius_scale: float | None = None) -> View: ...

    def photon_pass(self, scene: Scene, tracer: Tracer, view: View, pass_index: int, photons: int,
                    seed: int) -> PassEstimate: ...


class NoParams(BaseModel):
    """No parameters of its own (the walk's knobs are the run's `EstimatorSettings`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)


INTEGRATORS: Registry[Integrator] = Registry("method", where="simulate --method",
                                             implementations="lensmount.integrators")


def integrator(method: str, settings: EstimatorSettings | None = None, params: dict | None = None) -> Integrator:
    """The integrator `method` for a run with these settings."""
    return INTEGRATORS.create(method, params or {}, settings=settings or EstimatorSettings())


def check_method(method: str, field: str = "--method") -> None:
    """Refuse a method no integrator answers to."""
    INTEGRATORS.entry(method, field=field)


__all__ = ["Integrator", "SourceIndependentView", "NoParams", "INTEGRATORS", "integrator", "check_method"]
