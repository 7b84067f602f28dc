"""A part kind added the way docs/architecture.md says ("Where to add a part kind"): this file only.

Knife-edged vanes in the detector housing: `count` rings (the knife ring of knife_ring.py) spaced
evenly between the housing's front and `detector_gap_mm` before the image plane (neither end), each bore the beam
envelope over its thickness plus `margin_mm`, each outside the housing's bore. mount.toml places
them with

    [kinds.knife-vane]
    count = 3
"""

from __future__ import annotations

import math

import numpy as np
from knife_ring import KnifeRing
from pydantic import BaseModel, ConfigDict, Field

from lensmount.cad.plan import PartPlan
from lensmount.cad.stages import PART_KINDS, Mount
from lensmount.errors import GeometryError

KIND = "knife-vane"


class KnifeVaneParams(BaseModel):
    """[kinds.knife-vane]: how many knife-edged vanes the detector housing holds, and their size."""

    model_config = ConfigDict(extra="forbid")
    count: int = Field(0, ge=0, le=20, description="vanes in the housing (0: none)")
    thickness_mm: float = Field(1.0, gt=0, description="axial thickness")
    margin_mm: float = Field(0.5, ge=0, description="bore above the beam envelope")
    detector_gap_mm: float = Field(2.0, gt=0, description="the last vane's back face to the image plane")
    finish: str = "black-anodised"


def knife_vanes(params: KnifeVaneParams, *, mount: Mount) -> list[PartPlan]:
    """The knife vanes in the housing the built-in `housing` kind placed before this one."""
    if not params.count:
        return []
    housings = mount.of_kind("housing")
    if not housings or mount.of_kind("baffle"):
        raise GeometryError("knife vanes stand in the detector housing's free bore", field=f"kinds.{KIND}.count",
                            valid="0, or [housing] enabled = true with rear_baffle = false")
    h = housings[0].template
    z_in = h.z_front + (h.wall if h.flange_radius is not None else 0.0)
    z_out = float(mount.prescription.image_z) - params.detector_gap_mm
    t = params.thickness_mm
    if z_out - z_in < params.count * t:
        raise GeometryError(f"{params.count} knife vanes of {t} mm do not fit in the {z_out - z_in:.2f} mm between "
                            "the housing's front and the detector", field=f"kinds.{KIND}.count",
                            valid="fewer or thinner vanes, or a smaller detector_gap_mm")
    parts = []
    run = t / math.tan(math.radians(KnifeRing.bevel_deg))   # the knife's bevel, radially
    for z_back in z_in + t + (z_out - z_in - t) * np.arange(1, params.count + 1) / (params.count + 1):
        bore = mount.envelope.max_over(z_back - t, z_back) + params.margin_mm
        name = f"{KIND}-{len(parts) + 1}"
        if h.inner_radius - bore < run + mount.spec.vanes.min_height_mm:   # room for the bevel and a flat
            mount.notes.append(f"{name} at z = {z_back:.2f} mm left out: the beam fills the housing's bore there")
            continue
        ring = KnifeRing(z=float(z_back), bore_radius=float(bore), outer_radius=float(h.inner_radius), thickness=t)
        parts.append(PartPlan(name, KIND, mount.spec.finish_of(name, params.finish), ring))
    return parts


def register() -> None:
    PART_KINDS.register(KIND, KnifeVaneParams)(knife_vanes)
