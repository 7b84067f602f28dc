"""Part kinds the planner places around the lens stack, one stage each, created by name.

The planner (`cad.layout`) first seats the lenses in the barrel (lens groups, seats, spacers,
diaphragm, the barrel's bore); then every registered part kind, in the order registered, places its
parts from what is planned so far (`Mount`) and returns them. The built-in kinds (`hood`: the hood
and its vanes, `housing`: the detector housing and its rear baffle; `cad.kinds`) read their own
mount.toml tables; a plug-in kind registers the same way, and mount.toml sizes it in
`[kinds.NAME]`, checked by its parameter model (unknown keys, ranges, missing keys):

    class KnifeVaneParams(BaseModel):                      # in the plug-in's own file
        model_config = ConfigDict(extra="forbid")
        count: int = Field(0, ge=0)

    @PART_KINDS.register("knife-vane", KnifeVaneParams)
    def knife_vanes(params: KnifeVaneParams, *, mount: Mount) -> list[PartPlan]: ...

A stage places nothing it was not asked for (a kind absent from `[kinds]` gets its defaults), and
never moves what is placed: the parts it returns join the plan, and the profile checks
(`cad.checks`), the solids, the tessellation, drawings and BOM take them as they take the
built-in ones (`tests/recipes/knife_vanes.py`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict

from lensmount.cad.plan import Envelope, PartPlan
from lensmount.design.mount import MountSpec
from lensmount.optics.prescription import Prescription
from lensmount.registry import Registry


@dataclass(frozen=True)
class Mount:
    """What a part-kind stage reads: the lens, mount.toml, the beam, the barrel and what is placed so far.

    Args:
        prescription: the lens, with its clear semi-diameters.
        spec: mount.toml.
        envelope: the beam's radius at any z (`cad.plan.Envelope`).
        parts: every part placed so far, in order (the barrel first; earlier stages' parts after it).
        notes: what the plan tells the user; a stage appends its own (a part left out, and why).
        z_front: the barrel's front end, mm.
        z_back: the barrel's back end, mm.
        r_barrel: the barrel's outside radius, mm.
        bore_front: the barrel's bore at its front end, mm.
        bore_back: the barrel's bore at its back end, mm.
        aperture: (ρ, z) samples of the entrance aperture (the first surface over its clear aperture).
    """

    prescription: Prescription
    spec: MountSpec
    envelope: Envelope
    parts: tuple[PartPlan, ...]
    notes: list[str]
    z_front: float
    z_back: float
    r_barrel: float
    bore_front: float
    bore_back: float
    aperture: tuple[np.ndarray, np.ndarray]

    def of_kind(self, kind: str) -> list[PartPlan]:
        """The parts of one kind placed so far, in order."""
        return [p for p in self.parts if p.kind == kind]


class Stage(Protocol):
    """What a part kind registers: its parts, from its checked parameters and the plan so far."""

    def __call__(self, params: BaseModel, *, mount: Mount) -> list[PartPlan]: ...


PART_KINDS: Registry[list[PartPlan]] = Registry("part kind", where="mount.toml's [kinds] table")


class OwnTables(BaseModel):
    """A built-in kind is sized by its own mount.toml tables, so `[kinds.NAME]` takes no keys for it."""

    model_config = ConfigDict(extra="forbid")


def place_kinds(mount: Mount) -> list[PartPlan]:
    """Every registered part kind's parts, in the order the kinds were registered, each stage seeing
    the parts of the ones before it; the parameters of each from `[kinds.NAME]` (else its defaults)."""
    tables = mount.spec.kinds
    for name in tables:   # a table for no registered kind: an error naming the kinds there are
        PART_KINDS.entry(name, field=f"kinds.{name}")
    placed: list[PartPlan] = []
    for name in PART_KINDS.names():
        seen = replace(mount, parts=mount.parts + tuple(placed))
        placed += PART_KINDS.create(name, tables.get(name, {}), field=f"kinds.{name}", mount=seen)
    return placed


__all__ = ["Mount", "Stage", "PART_KINDS", "OwnTables", "place_kinds"]
