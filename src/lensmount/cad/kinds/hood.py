"""The built-in part kind `hood`: the front hood with its vanes, and the vanes inside long spacer tubes.

Vane bores are the real-ray beam envelope (full field, full pupil, every
wavelength) plus `vanes.aperture_margin_mm`, so a vane can never clip the beam;
a vane with less than `vanes.min_height_mm` of room above the beam is left out
and a note says so.

Hood vanes by line of sight (`vanes.placement = "line-of-sight"`), the classic
construction in the meridional plane: the first vane stands at the hood's mouth.
Behind vane k (bore r_k) the wall (radius R) is lit from z_k + w + (R − r_k)/tan θ_k
on, θ_k the steepest sun ray that passes every opening before it: parallel rays of
slope t pass coaxial openings (z_i, r_i) iff t·(z_j − z_i) ≤ r_i + r_j for every pair
(both ends of each vane's edge land), so deep in the hood only shallow rays arrive and
the lit wall starts far behind the vane. The next
vane's edge (the beam envelope + margin) is put where the line from that nearest lit
wall point to the entrance aperture across the axis (the first surface over its clear
aperture, whichever of its points gives the lowest line: the rim, or on a convex surface
an inner point nearer the vane) comes down to it: every lit point behind vane k is then
hidden from every point of the aperture. The construction stops
when no sun ray at the exclusion angle θ_e or beyond gets past the vanes
(tan θ_e > tan θ_k): the wall behind the last vane is dark.
The count follows from the construction.
"""

from __future__ import annotations

import numpy as np

from lensmount.cad.plan import PartPlan
from lensmount.cad.stages import PART_KINDS, Mount, OwnTables
from lensmount.design.mount import MountSpec
from lensmount.errors import GeometryError
from lensmount.templates.hood import Hood
from lensmount.templates.vane import Vane

HOOD_VANE_ROOM_MM = 4.0  # automatic hood bore: beam + vane margin + this much room for vanes


MAX_VANES = 40  # a construction that needs more has a hood far too long for its exclusion angle


def steepest_sun_slope(openings) -> float:
    """tan of the steepest parallel beam that passes every coaxial circular opening (z, r).

    Shifted by z·t the openings' discs must share a point; their centres lie on one line, so
    along it they are intervals and pairwise overlap suffices: t·(z_j − z_i) ≤ r_i + r_j.
    """
    z, r = np.asarray(openings, np.float64).T
    dz = z[None, :] - z[:, None]
    ahead = dz > 0
    return float(((r[:, None] + r[None, :])[ahead] / dz[ahead]).min()) if ahead.any() else np.inf


def line_of_sight(env, vs, wall: float, z_mouth: float, z_end: float, aperture: tuple[np.ndarray, np.ndarray],
                  exclusion_deg: float, notes: list[str]) -> list[float]:
    """Front-face z of the hood vanes by the classic construction (module docstring).

    Args: env the Envelope; vs the [vanes] table; wall the hood's bore radius R; z_mouth, z_end
    the hood's open and back ends; aperture (ρ, z) samples of the entrance aperture's profile
    from the axis to its rim (the first surface over its clear aperture).
    """
    rho, z_ap = (np.asarray(x, np.float64)[:, None] for x in aperture)
    tan_e = np.tan(np.radians(exclusion_deg))
    t, w, m = vs.thickness_mm, min(vs.edge_width_mm, vs.thickness_mm), vs.aperture_margin_mm
    last = z_end - t  # the deepest a vane's front face may sit
    grid = np.linspace(z_mouth, last, max(2, int(np.ceil((last - z_mouth) / 0.05)) + 1))
    bore = np.maximum(env.at(grid), env.at(grid + t)) + m  # vane edge radius (front face at grid z)

    def r_at(z):
        return float(np.interp(z, grid, bore))

    zs = [z_mouth]
    lands = [(z_mouth, r_at(z_mouth)), (z_mouth + w, r_at(z_mouth))]  # (z, r) of both ends of each edge land
    tan_max = steepest_sun_slope(lands)  # the steepest sun ray past the vanes so far
    while len(zs) < MAX_VANES:
        z, r = zs[-1], r_at(zs[-1])
        if tan_max < tan_e:
            return zs  # no sun ray at the exclusion angle or beyond gets past the vanes
        z_lit = max(z + t, z + w + (wall - r) / tan_max)  # the nearest wall point lit behind this vane
        if z_lit >= z_end:
            return zs
        # sight lines from the aperture across the axis (-ρ, z) to that wall point (R, z_lit): the
        # lowest at each z is the one a vane there must still reach; on a curved first surface it
        # need not come from the rim (an inner point can sit closer to the vane), and a vane
        # behind an aperture point cannot hide it
        lines = wall - (wall + rho) * (grid - z_lit) / (z_ap - z_lit)
        line = np.where(grid < z_ap, lines, -np.inf).min(axis=0)
        # the vane goes at the last z where the line still passes above a vane's edge (so it hits it)
        ok = (grid > z_lit) & (line <= bore)
        if not ok.any():
            notes.append(f"vanes: the wall lit from z = {z_lit:.2f} mm cannot be hidden inside the hood; "
                         "the last vane stands at its back end")
            return zs + [last] if last > z + t else zs
        z_next = float(grid[np.argmax(ok) - 1])
        if z_next <= z + t:
            notes.append(f"vanes: the construction stalls at z = {z:.2f} mm (vanes would overlap)")
            return zs
        # a sun ray behind the new vane has passed every edge land so far, not just the last two
        lands += [(z_next, r_at(z_next)), (z_next + w, r_at(z_next))]
        tan_max = steepest_sun_slope(lands)
        zs.append(z_next)
    notes.append(f"vanes: the construction stopped at {MAX_VANES} vanes")
    return zs


def hood_and_vanes(spec: MountSpec, env, z_front: float, r_barrel: float, bore_front: float,
                   spacers: list, notes: list[str], aperture: tuple[np.ndarray, np.ndarray], exclusion_deg: float):
    """(hood PartPlan or None, [vane PartPlan]) for a barrel whose front face is at z_front.

    Args:
        env: the layout's Envelope.
        z_front: z of the barrel's front face (the hood's back end), mm.
        r_barrel: barrel outside radius, mm. bore_front: barrel bore at its front, mm.
        spacers: the spacer PartPlans (long ones are tubes that hold vanes).
        notes: list the caller reports; vanes left out are noted here.
        aperture: (ρ, z) samples of the entrance aperture's profile from the axis to its rim (the first
            lens's surface over its clear aperture), as `line_of_sight` takes them.
        exclusion_deg: the smallest sun angle off the axis (line-of-sight vanes).
    """
    hood, vs, min_t = spec.hood, spec.vanes, spec.checks.min_thickness_mm
    vanes: list[tuple[float, float, float]] = []  # (z_front, inner, outer)
    hood_part = None
    if hood.enabled:
        z_mouth = z_front - hood.length_mm
        beam_in_hood = env.max_over(z_mouth, z_front)
        if hood.inner_diameter_mm is not None:
            ri = 0.5 * hood.inner_diameter_mm
        else:
            ri = beam_in_hood + vs.aperture_margin_mm + HOOD_VANE_ROOM_MM
        if ri < beam_in_hood:
            raise GeometryError(f"the hood's bore (radius {ri:.3f} mm) cuts the beam (radius {beam_in_hood:.3f} mm) "
                                f"by {beam_in_hood - ri:.3f} mm", field="hood.inner_diameter_mm",
                                valid=f"an inner diameter above {2 * beam_in_hood:.2f} mm")
        # a flange closes the annulus between a hood wider than the barrel and the barrel's face
        flange, z_inner_end = None, z_front
        if ri >= r_barrel - min_t:
            rf = max(bore_front, env.max_over(z_front - hood.wall_mm, z_front) + vs.aperture_margin_mm)
            if rf < r_barrel - min_t:
                flange, z_inner_end = float(rf), z_front - hood.wall_mm
            else:
                notes.append("hood: no room for a back flange between the beam and the barrel's outside")
        hood_part = PartPlan("hood", "hood", spec.finish_of("hood", hood.finish),
                             Hood(float(z_mouth), float(z_front), float(ri), float(ri + hood.wall_mm),
                                  flange, hood.wall_mm))
        if vs.positions_mm is not None:
            zs = [float(z) for z in vs.positions_mm]
            for z in zs:
                if not (z_mouth <= z <= z_inner_end - vs.thickness_mm):
                    raise GeometryError(f"vane position {z} mm lies outside the hood "
                                        f"({z_mouth:.2f} .. {z_inner_end - vs.thickness_mm:.2f} mm)",
                                        field="vanes.positions_mm", valid="z values inside the hood")
        elif vs.placement == "line-of-sight":
            zs = line_of_sight(env, vs, ri, z_mouth, z_inner_end, aperture, exclusion_deg, notes)
        else:  # evenly from the mouth to the back of the hood
            span = z_inner_end - z_mouth - vs.thickness_mm
            zs = [z_mouth + span * k / max(vs.count - 1, 1) for k in range(vs.count)]
        for z in zs:
            vanes.append((z, env.max_over(z, z + vs.thickness_mm) + vs.aperture_margin_mm, ri))
    for sp_plan in spacers:
        sp = sp_plan.template
        if sp.tube_radius is None or vs.in_air_gaps == 0:
            continue
        za, zb = sp.front_z + sp.lip, sp.back_z - sp.lip
        for k in range(vs.in_air_gaps):
            z = za + (zb - za) * (k + 1) / (vs.in_air_gaps + 1) - 0.5 * vs.thickness_mm
            vanes.append((z, env.max_over(z, z + vs.thickness_mm) + vs.aperture_margin_mm, sp.tube_radius))
    vane_parts = []
    for z, r_in, r_out in sorted(vanes):
        if r_out - r_in < max(vs.min_height_mm, 1e-3):
            notes.append(f"vane at z = {z:.2f} mm left out: only {r_out - r_in:.3f} mm of room above the beam")
            continue
        name = f"vane-{len(vane_parts) + 1}"
        vane_parts.append(PartPlan(name, "vane", spec.finish_of(name, vs.finish),
                                   Vane(float(z), float(r_in), float(r_out), vs.thickness_mm,
                                        vs.edge_width_mm, vs.bevel_angle_deg)))
    return hood_part, vane_parts


@PART_KINDS.register("hood", OwnTables)
def hood_stage(params: OwnTables, *, mount: Mount) -> list[PartPlan]:
    """The hood in front of the barrel with its vanes, and the vanes in long spacer tubes ([hood], [vanes])."""
    hood_part, vane_parts = hood_and_vanes(mount.spec, mount.envelope, mount.z_front, mount.r_barrel, mount.bore_front,
                                           mount.of_kind("spacer"), mount.notes, mount.aperture,
                                           mount.spec.exclusion_deg(mount.prescription.max_field_deg))
    return ([hood_part] if hood_part is not None else []) + vane_parts


__all__ = ["hood_and_vanes", "steepest_sun_slope", "hood_stage"]
