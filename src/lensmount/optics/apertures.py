"""Clear apertures from the real beam, and the beam envelope for the mount.

`with_clear_semi_diameters` does what Zemax does for "automatic" semi-diameters:
trace real rays (real-ray aiming at the stop) for every field, at the full
pupil (as the file's vignetting factors leave it) and every wavelength, and take
the largest ray height on each surface, plus a margin. The stop's clear semi-diameter is the stop semi-diameter set by
the aperture (no margin: the diaphragm *is* the aperture).

`beam_envelope` gives the radius of the beam at any z of the assembly frame, for
vane and spacer checks. The field is rotationally symmetric, so a meridional fan
of field angles 0..max covers the negative and the skew fields too (a field at
azimuth psi is the meridional one rotated by psi: same radii).
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np

from lensmount.errors import InputError
from lensmount.optics.prescription import Prescription
from lensmount.optics.realrays import RealRays, aim, plane_crossing, pupil_rings, stop_semi_diameter, trace

# Pupil sampling for the envelope: the rim error of a polygon of S spokes on a
# circle of radius R is R (1 - cos(pi/S)); 180 spokes keep it below 0.01 mm for
# R = 60 mm. Interior rings catch caustics near foci.
ENVELOPE_RINGS = 8
ENVELOPE_SPOKES = 180
ENVELOPE_FIELDS = 11  # evenly from 0 to the largest field, plus the listed fields
CLEAR_RINGS = 4
CLEAR_SPOKES = 180


def _field_samples(prescription: Prescription, n: int) -> np.ndarray:
    listed = np.abs(np.asarray(prescription.field_values, dtype=np.float64))
    fan = np.linspace(0.0, listed.max(), n) if n > 1 else np.zeros(1)
    return np.unique(np.concatenate([listed, fan]))


def vignetted_pupils(prescription: Prescription, fields, pupil) -> np.ndarray:
    """(F, P, 2) the pupil points each field's designed beam fills: `pupil` mapped by the file's
    vignetting factors (Prescription.vignetting), linearly interpolated between the listed fields
    and held beyond them; the plain pupil for every field when the lens has none."""
    fields = np.abs(np.atleast_1d(np.asarray(fields, dtype=np.float64)))
    pupil = np.asarray(pupil, dtype=np.float64).reshape(-1, 2)
    if not prescription.vignetting:
        return np.broadcast_to(pupil, (len(fields), len(pupil), 2))
    listed = np.abs(np.asarray(prescription.field_values, dtype=np.float64))
    order = np.argsort(listed)
    table = np.asarray(prescription.vignetting, dtype=np.float64)[order]
    vdx, vdy, vcx, vcy, van = (np.interp(fields, listed[order], table[:, k])[:, None] for k in range(5))
    x = vdx + pupil[None, :, 0] * (1.0 - vcx)
    y = vdy + pupil[None, :, 1] * (1.0 - vcy)
    a = np.radians(van)
    return np.stack([x * np.cos(a) - y * np.sin(a), x * np.sin(a) + y * np.cos(a)], axis=-1)


def _beam(prescription: Prescription, fields, pupil, clip: bool):
    """Traces of every wavelength: list of RealRays."""
    out = []
    r_stop = stop_semi_diameter(prescription)
    for wl in prescription.wavelengths_um:
        o, d = aim(prescription, fields, pupil, wl, stop_radius=r_stop)
        out.append(trace(prescription, o, d, wl, clip=clip))
    return out


@lru_cache(maxsize=8)  # a pure function of a frozen lens: init, regenerate and simulate each load it
def with_clear_semi_diameters(prescription: Prescription, margin_mm: float = 0.0) -> Prescription:
    """The prescription with automatic clear semi-diameters where it gives none.

    Surfaces that have a clear semi-diameter keep it (and vignette the rays beyond it).
    Raises InputError (field `surface[i].radius`, 1-based i) when the beam misses a
    surface, i.e. its radius is smaller than the semi-diameter the beam needs.
    """
    if margin_mm < 0:
        raise InputError(f"clear-aperture margin {margin_mm} mm is negative", field="margin_mm",
                         valid="a margin >= 0 mm")
    heights, missed = beam_heights(prescription)
    if missed is not None:
        s = prescription.surfaces[missed]
        raise InputError(
            f"rays of the full field and aperture miss surface {missed + 1} (radius {s.radius:g} mm) "
            "or are totally reflected there: its radius is smaller than the semi-diameter the beam needs, "
            "or a surface before it bends the beam too far",
            field=f"surface[{missed + 1}].radius",
            valid="a |radius| larger than the beam's semi-diameter on that surface (or radii before it "
                  "that bend the beam less), or a smaller aperture or field")
    stop = prescription.stop_index
    out = []
    for i, s in enumerate(prescription.surfaces):
        if s.clear_semi_diameter is not None:
            out.append(s.clear_semi_diameter)
        elif i == stop and not prescription.object_telecentric:  # telecentric: the stop does not aim
            out.append(stop_semi_diameter(prescription))
        else:
            out.append(float(heights[i]) + margin_mm)
    return prescription.with_clear_semi_diameters(out)


def beam_heights(prescription: Prescription) -> tuple[np.ndarray, int | None]:
    """(S,) the largest real-ray height on each surface over the fields (and their mirror images), the
    full pupil (the file's vignetting factors applied) and every wavelength, with real-ray aiming at the
    stop, of the rays that reach it; and the first surface (0-based) where rays are lost though it gives
    no clear semi-diameter (they miss it or are totally reflected), None when there is none. Surfaces
    with a clear semi-diameter clip the beam (those rays are legitimately vignetted)."""
    fields = _field_samples(prescription, 6)
    # a beam decentred across (VDX) or turned (VAN) is not mirror-symmetric in x: the whole pupil then
    symmetric = all(v[0] == 0.0 and v[4] == 0.0 for v in prescription.vignetting)
    pupil = vignetted_pupils(prescription, fields, pupil_rings(CLEAR_RINGS, CLEAR_SPOKES, half=symmetric))
    nsurf = len(prescription.surfaces)
    heights = np.zeros(nsurf)
    given = np.array([s.clear_semi_diameter is not None for s in prescription.surfaces])
    missed = None
    for rays in _beam(_stop_passing_the_rim(prescription), fields, pupil, clip=True):
        at = rays.vignetted_at
        lost = at[(at >= 0) & (at < nsurf)]
        lost = lost[~given[lost]]
        if len(lost):
            missed = int(lost.min()) if missed is None else min(missed, int(lost.min()))
        # a ray counts on surface j if it reached it (arrived, or stopped at a later surface)
        reached = (at[None, :] < 0) | (at[None, :] > np.arange(nsurf)[:, None])
        h = np.where(reached, rays.heights()[:nsurf], 0.0)
        heights = np.maximum(heights, h.max(axis=1))
    return heights, missed


LOSS_PUPIL_STEP = 0.02  # pupil grid pitch (normalised): ~7 850 points, a loss resolved to ~0.02 %


def pupil_lost_at(prescription: Prescription, surface_sets, fields) -> np.ndarray:
    """(S, F) per set of surfaces (0-based) in `surface_sets`, the fraction of each field's designed
    pupil (the file's vignetting factors applied, equal areas of the unit disc) whose rays stop at
    one of them, the worst wavelength. One trace of the beam serves every set.

    The stop passes its rim as for the automatic semi-diameters, so only what the sets clip counts.
    """
    g = np.arange(-1.0 + 0.5 * LOSS_PUPIL_STEP, 1.0, LOSS_PUPIL_STEP)
    x, y = np.meshgrid(g, g)
    disc = np.column_stack([x.ravel(), y.ravel()])
    disc = disc[np.einsum("ij,ij->i", disc, disc) <= 1.0]
    fields = np.atleast_1d(np.asarray(fields, dtype=np.float64))
    pupil = vignetted_pupils(prescription, fields, disc)
    sets = [np.asarray(list(surfaces), dtype=np.int64) for surfaces in surface_sets]
    lost = np.zeros((len(sets), len(fields)))
    for rays in _beam(_stop_passing_the_rim(prescription), fields, pupil, clip=True):
        for k, idx in enumerate(sets):
            stopped = np.isin(rays.vignetted_at, idx).reshape(len(fields), -1)
            lost[k] = np.maximum(lost[k], stopped.mean(axis=1))
    return lost


def beam_envelope(prescription: Prescription, z, land: tuple[float, float, float] | None = None) -> np.ndarray:
    """Largest radius of any ray of the full field and aperture at each z.

    Args:
        prescription: the lens; surfaces with a clear semi-diameter vignette the beam
            (a ray counts up to the surface that stops it).
        z: (n,) z values, mm, assembly frame. In front of surface 1 the beam is
            collimated per field (straight lines); behind the image plane the rays
            continue straight.
        land: (z0, z1, radius) of a diaphragm's land: only the rays it passes count
            (`beam_through_land`).
    Returns:
        (n,) radius in mm (all wavelengths, fields 0..max, full pupil).
    """
    zq = np.atleast_1d(np.asarray(z, dtype=np.float64))
    env = np.zeros(len(zq))
    for rays in (_envelope_beam(prescription) if land is None else beam_through_land(prescription, land)):
        env = np.maximum(env, _polyline_radius(rays, zq))
    return env


@lru_cache(maxsize=4)
def beam_through_land(prescription: Prescription, land: tuple[float, float, float]) -> tuple[RealRays, ...]:
    """The rays of the full field and aperture that a diaphragm's land (a bore of radius r from z0 to
    z1, in air) passes. The land is the stop the mount realises: it passes the designed axial beam
    (`cad.seats.pupil_edge_radius`), but it lies off the stop surface when that is a curved face
    (no metal fits on glass), so an off-axis beam crosses it displaced from where the stop surface
    has it, by the distance times the rays' slope (the Cooke triplet's 20° beam: 35 µm): the land
    stops a sliver of the beam aimed at the stop surface and passes as much on the other side.
    Kept: the envelope beam's rays inside r at z0 and z1 (a straight ray's radius is convex in z,
    so inside over the whole land), and the passed beam's rim, rays aimed at the land's rim at
    either end that pass the other end. Telecentric object space: the land passes every field
    whole (`pupil_edge_radius`), the envelope beam itself."""
    z0, z1, r = land
    fields = _field_samples(prescription, ENVELOPE_FIELDS)
    rim = pupil_rings(1, ENVELOPE_SPOKES, center=False, half=True)
    stop = prescription.stop_index   # the land replaces the stop: the stop face's own semi-diameter clips nothing
    lens = prescription.with_surfaces([replace(s, clear_semi_diameter=None) if i == stop else s
                                       for i, s in enumerate(prescription.surfaces)])
    out = []
    for rays in _envelope_beam(prescription):
        wl = rays.wavelength_um
        sets = [rays]
        if not prescription.object_telecentric:
            for plane in (z0, z1):
                o, d = aim(lens, fields, rim, wl, stop_radius=r, at_z=plane)
                sets.append(trace(lens, o, d, wl, clip=True))
        for s in sets:
            keep = np.ones(s.points.shape[1], bool)
            for plane in (z0, z1):
                xy, reached = plane_crossing(s, plane)
                keep &= reached & (np.hypot(xy[:, 0], xy[:, 1]) <= r + _LAND_TOL_MM)
            if keep.any():
                out.append(RealRays(s.points[:, keep], s.directions[:, keep], s.vignetted[keep], s.vignetted_at[keep],
                                    s.origins[keep], s.start_directions[keep], wl))
    return tuple(out)


_LAND_TOL_MM = 1e-6   # a ray aimed at the land's rim passes it (the aim lands within 1e-10 mm)


@lru_cache(maxsize=4)  # ~14 MB a lens (3 colours x 8000 rays x 12 surfaces)
def _envelope_beam(prescription: Prescription) -> tuple:
    """The envelope's traced rays, kept per prescription (frozen, so equal lenses share them): the
    layout, the starter mount and the checks ask for the envelope of one lens a dozen times at
    different z, and the real-ray aiming is most of a regenerate's time. Callers only read them."""
    fields = _field_samples(prescription, ENVELOPE_FIELDS)
    pupil = pupil_rings(ENVELOPE_RINGS, ENVELOPE_SPOKES, half=True)
    beam = tuple(_beam(_stop_passing_the_rim(prescription), fields, pupil, clip=True))
    for rays in beam:
        for value in vars(rays).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
    return beam


def _stop_passing_the_rim(prescription: Prescription) -> Prescription:
    """The lens with a stop that passes the rays aimed at its rim. The mount's diaphragm passes the
    designed pupil (cad.seats.pupil_edge_radius), so a stop DIAM a hair under the height at which the
    real axial ray at EPD/2 crosses it (the Cooke triplet's 3.8 mm for 3.861 mm) must not drop the rim rays
    the beam is aimed with from the envelope or the automatic semi-diameters behind it."""
    stop = prescription.surfaces[prescription.stop_index]
    r_stop = (1.0 + 1e-6) * stop_semi_diameter(prescription)
    if stop.clear_semi_diameter is None or stop.clear_semi_diameter >= r_stop or prescription.object_telecentric:
        return prescription
    surfaces = list(prescription.surfaces)
    surfaces[prescription.stop_index] = replace(stop, clear_semi_diameter=r_stop)
    return prescription.with_surfaces(surfaces)


def _polyline_radius(rays, zq: np.ndarray) -> np.ndarray:
    """Max over rays of the radius where each ray's path crosses each z in zq: (n,)."""
    pts = rays.points  # (S+1, N, 3): surfaces then image plane
    nseg = len(pts) - 1
    last_ok = np.where(rays.vignetted_at < 0, nseg, rays.vignetted_at)  # segments j < last_ok exist
    env2 = np.zeros(len(zq))  # squared: the root is taken once, at the end

    def update(sel, origin, slope, lo, hi):
        """Rays x = origin + z·slope (x, y per ray) for lo <= z <= hi; only the queries inside the
        rays' z range are evaluated, chunked to keep (chunk, N) small."""
        idx = np.flatnonzero(sel & (zq >= lo.min()) & (zq <= hi.max()))
        chunk = max(1, int(2_000_000 // max(1, len(lo))))
        for a in range(0, len(idx), chunk):
            part = idx[a:a + chunk]
            zc = zq[part][:, None]
            x = origin[:, 0] + zc * slope[:, 0]
            y = origin[:, 1] + zc * slope[:, 1]
            r2 = np.where((zc >= lo) & (zc <= hi), x * x + y * y, 0.0)
            env2[part] = np.maximum(env2[part], r2.max(axis=1))

    def straight(p, d, keep, lo, hi):
        """Straight rays p + s·d (the launch before surface 1, the last leg after the image plane)."""
        p, d, lo, hi = p[keep], d[keep], lo[keep], hi[keep]
        dz = np.where(np.abs(d[:, 2]) > 1e-15, d[:, 2], 1e-15)
        slope = d[:, :2] / dz[:, None]
        update(np.ones(len(zq), bool), p[:, :2] - p[:, 2:3] * slope, slope, lo, hi)

    # before the first surface: straight lines along the launch direction
    n = pts.shape[1]
    straight(pts[0], rays.start_directions, np.ones(n, bool), np.full(n, -np.inf), pts[0][:, 2])
    # after the image plane: straight on
    arrived = rays.vignetted_at < 0
    if arrived.any():
        straight(pts[-1], rays.directions[-1], arrived, pts[-1][:, 2], np.full(n, np.inf))
    for j in range(nseg):
        exists = j < last_ok
        if not exists.any():
            continue
        p0, p1 = pts[j][exists], pts[j + 1][exists]
        z0, z1 = p0[:, 2], p1[:, 2]
        dz = z1 - z0
        flat = np.abs(dz) <= 1e-15   # met only at z0 itself, at p0
        slope = np.where(flat[:, None], 0.0, (p1[:, :2] - p0[:, :2]) / np.where(flat, 1.0, dz)[:, None])
        update(np.ones(len(zq), bool), p0[:, :2] - z0[:, None] * slope, slope, np.minimum(z0, z1), np.maximum(z0, z1))
    return np.sqrt(env2)


__all__ = ["with_clear_semi_diameters", "beam_heights", "vignetted_pupils", "pupil_lost_at", "beam_envelope", "beam_through_land"]
