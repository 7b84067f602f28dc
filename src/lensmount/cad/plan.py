"""What a mount plan is made of, shared by every planner and by what reads a plan: the parts
(`PartPlan`), the contacts on the glass (`Contact`), the plan itself (`Layout`) and the beam
envelope the parts keep clear of (`Envelope`). Pure numbers, no CAD kernel, no planning: the
planners (`cad.layout`, `cad.catadioptric`) and the stages they are made of write these; checks,
the assembly and the drawings read them."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Protocol

import numpy as np

from lensmount.cad.step_parts import StepSource
from lensmount.optics.apertures import beam_envelope
from lensmount.optics.prescription import Prescription
from lensmount.templates.lens_element import GroupOutline
from lensmount.templates.profile import Template

ENVELOPE_STEP_MM = 0.25


class BeamCheck(Protocol):
    """A folded path's rays, which the beam check tests the mechanical profiles against instead of the
    envelope (`cad.catadioptric.BeamPaths`)."""

    def check(self, layout: Layout, outlines: dict[str, np.ndarray]) -> None: ...


@dataclass
class PartPlan:
    """One part: name, kind, finish and what it is made from: the template that builds it, a stepped
    cemented group's `GroupOutline` (it stands in for its elements where seats are planned; never
    built), or the user's STEP file (`cad.step_parts.StepSource`: the solid comes from the file)."""

    name: str
    kind: str
    finish: str
    template: Template | GroupOutline | StepSource


@dataclass
class Contact:
    """A mechanical contact on an optical surface (for the clear-aperture check)."""

    part: str
    lens: str
    surface: int
    height: float
    clear: float


@dataclass
class Layout:
    prescription: Prescription  # with clear semi-diameters
    parts: list[PartPlan]
    contacts: list[Contact]
    envelope: Envelope
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # built, but the user should act or know (allowed vignetting)
    beam: BeamCheck | None = None  # a folded path's rays: the beam check runs on them

    def part(self, name: str) -> PartPlan:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(name)


class Envelope:
    """Beam envelope radius at any z, interpolated from a fine grid of real-ray envelopes.

    In an air gap each ray's radius is a convex function of z, so the envelope is
    convex there and the chord between two grid values bounds it from above; across
    a surface it is only an approximation, which is why `exact` exists for checks.
    """

    def __init__(self, prescription: Prescription, z_min: float, z_max: float, step: float = ENVELOPE_STEP_MM):
        n = max(2, int(np.ceil((z_max - z_min) / step)) + 1)
        self.prescription = prescription
        self.z = np.linspace(z_min, z_max, n)
        self.r = _envelope_grid(prescription, float(z_min), float(z_max), n)

    def exact(self, z, land: tuple[float, float, float] | None = None) -> np.ndarray:
        """The real-ray envelope at each z (slow: traces the beam), (n,); with a diaphragm's land
        (z0, z1, radius), of the rays it passes (`optics.apertures.beam_through_land`)."""
        return _exact_envelope(self.prescription, z, land)

    def at(self, z) -> np.ndarray:
        """Envelope at each z by linear interpolation: (n,)."""
        return np.interp(np.asarray(z, dtype=np.float64), self.z, self.r)

    def max_over(self, z0: float, z1: float) -> float:
        """Largest envelope radius for z in [z0, z1], mm."""
        a, b = min(z0, z1), max(z0, z1)
        inside = self.r[(self.z > a) & (self.z < b)]
        ends = self.at([a, b])
        return float(max(ends.max(), inside.max() if len(inside) else 0.0))


@lru_cache(maxsize=8)
def _envelope_grid(prescription: Prescription, z_min: float, z_max: float, n: int) -> np.ndarray:
    """Envelope radii on a grid, kept per lens and grid (read-only): `init` checks the starter mount
    with the same layout that `regenerate` then plans, and a design loop replans one lens often."""
    r = _exact_envelope(prescription, np.linspace(z_min, z_max, n))
    r.flags.writeable = False
    return r


def _exact_envelope(prescription: Prescription, z, land=None) -> np.ndarray:
    z = np.atleast_1d(np.asarray(z, dtype=np.float64))
    if not len(z):
        return np.zeros(0)
    return np.nan_to_num(beam_envelope(prescription, z, land), nan=0.0, posinf=0.0, neginf=0.0)


__all__ = ["PartPlan", "Contact", "Layout", "Envelope", "BeamCheck", "ENVELOPE_STEP_MM"]
