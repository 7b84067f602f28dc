"""The built-in part kind `housing`: the detector housing behind the barrel and its rear baffle ([housing])."""

from __future__ import annotations

import numpy as np

from lensmount.cad.plan import PartPlan
from lensmount.cad.stages import PART_KINDS, Mount, OwnTables
from lensmount.design.mount import MountSpec
from lensmount.errors import GeometryError
from lensmount.templates.housing import Housing
from lensmount.templates.rear_baffle import RearBaffle

REAR_BAFFLE_STEP_MM = 2.0  # spacing of the rear baffle's bore samples (the chord of a convex envelope clears it)


def housing(spec: MountSpec, env, image_z: float, z_back: float, r_barrel: float, bore_back: float,
            notes: list[str]):
    """(housing PartPlan or None, rear baffle PartPlan or None).

    The housing runs from the barrel's back face (z_back) to `back_gap_mm` behind the image
    plane, its bore clear of the detector's corners and of the beam; a front flange closes it
    against a narrower barrel (r_barrel outside, bore_back bore at the back face). With
    `rear_baffle`, a tube inside it from the barrel (or the flange) to `rear_baffle_gap_mm`
    before the image plane has a bore through the beam envelope + `rear_baffle_margin_mm`
    at samples REAR_BAFFLE_STEP_MM apart: in air the envelope is convex in z (the largest of
    straight rays' |r|), so the chords between samples stay outside it. The housing's bore
    grows to leave the baffle `rear_baffle_wall_mm` of wall.
    """
    hs = spec.housing
    if not hs.enabled:
        if hs.rear_baffle:
            raise GeometryError("a rear baffle sits in the detector housing, which is disabled",
                                field="housing.rear_baffle", valid="false, or [housing] enabled = true")
        return None, None
    half_diag = 0.5 * float(np.hypot(hs.detector_width_mm, hs.detector_height_mm))
    z_wall = image_z + hs.back_gap_mm
    min_t = spec.checks.min_thickness_mm
    if z_wall <= z_back + min_t:
        raise GeometryError("the housing would end before the barrel does", field="housing.back_gap_mm",
                            valid="a larger back gap")
    r_h = max(half_diag + hs.detector_clearance_mm, env.max_over(z_back, image_z) + spec.vanes.aperture_margin_mm)
    bore = None
    if hs.rear_baffle:
        z_end = image_z - hs.rear_baffle_gap_mm
        n = max(2, int(np.ceil((z_end - z_back) / REAR_BAFFLE_STEP_MM)) + 1)
        zs = np.linspace(z_back, z_end, n)
        bore = env.exact(zs) + hs.rear_baffle_margin_mm
        r_h = max(r_h, float(bore.max()) + hs.rear_baffle_wall_mm + spec.spacers.radial_clearance_mm)
    flange = None
    if r_h >= r_barrel - min_t:
        rf = max(bore_back, env.max_over(z_back, z_back + hs.wall_mm) + spec.vanes.aperture_margin_mm)
        if rf < r_barrel - min_t:
            flange = float(rf)
        else:
            notes.append("housing: no room for a front flange between the beam and the barrel's outside")
    housing_part = PartPlan("housing", "housing", spec.finish_of("housing", hs.finish),
                            Housing(float(z_back), float(z_wall), float(r_h), hs.wall_mm, flange))
    if bore is None:
        return housing_part, None
    z_front = z_back + (hs.wall_mm if flange is not None else 0.0)  # on the flange's inside, else the barrel
    if zs[-1] - z_front < min_t:
        raise GeometryError(f"no room for the rear baffle: the housing's front (z = {z_front:.2f} mm) lies "
                            f"{z_front - zs[-1]:.2f} mm behind its back end", field="housing.rear_baffle_gap_mm",
                            valid="a smaller gap to the detector, or rear_baffle = false")
    zs = np.concatenate([[z_front], zs[zs > z_front + 1e-6]])
    bore = env.exact(zs) + hs.rear_baffle_margin_mm
    baffle = RearBaffle(tuple((float(r), float(z)) for r, z in zip(bore, zs)),
                        float(r_h - spec.spacers.radial_clearance_mm))
    return housing_part, PartPlan("rear-baffle", "baffle", spec.finish_of("rear-baffle", hs.finish), baffle)


@PART_KINDS.register("housing", OwnTables)
def housing_stage(params: OwnTables, *, mount: Mount) -> list[PartPlan]:
    """The detector housing behind the barrel and its rear baffle ([housing])."""
    parts = housing(mount.spec, mount.envelope, mount.prescription.image_z, mount.z_back, mount.r_barrel,
                    mount.bore_back, mount.notes)
    return [part for part in parts if part is not None]


__all__ = ["housing", "housing_stage"]
