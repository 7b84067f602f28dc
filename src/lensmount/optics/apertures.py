"""Clear apertures from the real beam, and the beam envelope for the mount.

`with_clear_semi_diameters` does what Zemax does for "automatic" semi-diameters:
trace real rays (real-ray aiming at the stop) for every field, at the full
pupil and every wavelength, and take the largest ray height on each surface,
plus a margin. The stop's clear semi-diameter is the stop semi-diameter set by
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
from lensmount.optics.realrays import aim, pupil_rings, stop_semi_diameter, trace

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


def _beam(prescription: Prescription, fields, pupil, clip: bool):
    """Traces of every wavelength: list of RealRays."""
    out = []
    r_stop = stop_semi_diameter(prescription)
    for wl in prescription.wavelengths_um:
        o, d = aim(prescription, fields, pupil, wl, stop_radius=r_stop)
        out.append(trace(prescription, o, d, wl, clip=clip))
    return out


def with_clear_semi_diameters(prescription: Prescription, margin_mm: float = 0.0) -> Prescription:
    """The prescription with automatic clear semi-diameters where it gives none.

    Surfaces that have a clear semi-diameter keep it (and vignette the rays beyond it).
    Raises InputError (field `surface[i].radius`, 1-based i) when the beam misses a
    surface, i.e. its radius is smaller than the semi-diameter the beam needs.
    """
    if margin_mm < 0:
        raise InputError(f"clear-aperture margin {margin_mm} mm is negative", field="margin_mm",
                         valid="a margin >= 0 mm")
    stop = prescription.stop_index
    fields = _field_samples(prescription, 6)
    pupil = pupil_rings(CLEAR_RINGS, CLEAR_SPOKES, half=True)
    nsurf = len(prescription.surfaces)
    heights = np.zeros(nsurf)
    given = np.array([s.clear_semi_diameter is not None for s in prescription.surfaces])
    # Surfaces with a given clear semi-diameter clip the beam (those rays are legitimately
    # vignetted); a ray stopped where nothing clips missed the surface or met TIR.
    for rays in _beam(prescription, fields, pupil, clip=True):
        at = rays.vignetted_at
        lost = at[(at >= 0) & (at < nsurf)]
        lost = lost[~given[lost]]
        if len(lost):
            i = int(lost.min())
            s = prescription.surfaces[i]
            raise InputError(
                f"rays of the full field and aperture miss surface {i + 1} (radius {s.radius:g} mm) "
                "or are totally reflected there: the radius is smaller than the semi-diameter the beam needs",
                field=f"surface[{i + 1}].radius",
                valid="a |radius| larger than the beam's semi-diameter on that surface, "
                      "or a smaller aperture or field")
        # a ray counts on surface j if it reached it (arrived, or stopped at a later surface)
        reached = (at[None, :] < 0) | (at[None, :] > np.arange(nsurf)[:, None])
        h = np.where(reached, rays.heights()[:nsurf], 0.0)
        heights = np.maximum(heights, h.max(axis=1))
    out = []
    for i, s in enumerate(prescription.surfaces):
        if s.clear_semi_diameter is not None:
            out.append(s.clear_semi_diameter)
        elif i == stop:
            out.append(stop_semi_diameter(prescription))
        else:
            out.append(float(heights[i]) + margin_mm)
    return prescription.with_clear_semi_diameters(out)


def beam_envelope(prescription: Prescription, z) -> np.ndarray:
    """Largest radius of any ray of the full field and aperture at each z.

    Args:
        prescription: the lens; surfaces with a clear semi-diameter vignette the beam
            (a ray counts up to the surface that stops it).
        z: (n,) z values, mm, assembly frame. In front of surface 1 the beam is
            collimated per field (straight lines); behind the image plane the rays
            continue straight.
    Returns:
        (n,) radius in mm (all wavelengths, fields 0..max, full pupil).
    """
    zq = np.atleast_1d(np.asarray(z, dtype=np.float64))
    env = np.zeros(len(zq))
    for rays in _envelope_beam(prescription):
        env = np.maximum(env, _polyline_radius(rays, zq))
    return env


@lru_cache(maxsize=8)
def _envelope_beam(prescription: Prescription) -> tuple:
    """The envelope's traced rays, kept per prescription (frozen, so equal lenses share them): the
    layout, the starter mount and the checks ask for the envelope of one lens a dozen times at
    different z, and the real-ray aiming is most of a regenerate's time. Callers only read them."""
    fields = _field_samples(prescription, ENVELOPE_FIELDS)
    pupil = pupil_rings(ENVELOPE_RINGS, ENVELOPE_SPOKES, half=True)
    # The mount's diaphragm passes the designed pupil (cad.layout.pupil_edge_radius), so a stop
    # DIAM rounded a hair under the marginal ray (the Cooke triplet's 3.8 mm for 3.8046 mm) must
    # not drop the rim rays, which the diaphragm lets through, from the envelope.
    stop = prescription.surfaces[prescription.stop_index]
    r_stop = (1.0 + 1e-6) * stop_semi_diameter(prescription)
    if stop.clear_semi_diameter is not None and stop.clear_semi_diameter < r_stop:
        surfaces = list(prescription.surfaces)
        surfaces[prescription.stop_index] = replace(stop, clear_semi_diameter=r_stop)
        prescription = prescription.with_surfaces(surfaces)
    beam = tuple(_beam(prescription, fields, pupil, clip=True))
    for rays in beam:
        for value in vars(rays).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
    return beam


def _polyline_radius(rays, zq: np.ndarray) -> np.ndarray:
    """Max over rays of the radius where each ray's path crosses each z in zq: (n,)."""
    pts = rays.points  # (S+1, N, 3): surfaces then image plane
    nseg = len(pts) - 1
    last_ok = np.where(rays.vignetted_at < 0, nseg, rays.vignetted_at)  # segments j < last_ok exist
    env = np.zeros(len(zq))

    def update(sel, radius_fn):
        # Only the queries inside a piece's z range are evaluated; chunked to keep (chunk, N) small.
        idx = np.flatnonzero(sel)
        chunk = max(1, int(2_000_000 // max(1, pts.shape[1])))
        for a in range(0, len(idx), chunk):
            part = idx[a:a + chunk]
            env[part] = np.maximum(env[part], radius_fn(zq[part][:, None]).max(axis=1))

    # before the first surface: straight lines along the launch direction
    z_first = pts[0][:, 2]
    update(zq <= z_first.max(),
           lambda zc: _ray_radius_at(pts[0], rays.start_directions, zc, upper=z_first))
    # after the image plane: straight on
    z_last = pts[-1][:, 2]
    arrived = rays.vignetted_at < 0
    if arrived.any():
        update(zq >= z_last[arrived].min(),
               lambda zc: _ray_radius_at(pts[-1], rays.directions[-1], zc, lower=z_last, valid=arrived))
    for j in range(nseg):
        p0, p1 = pts[j], pts[j + 1]
        z0, z1 = p0[:, 2], p1[:, 2]
        lo, hi = np.minimum(z0, z1), np.maximum(z0, z1)
        exists = j < last_ok
        if not exists.any():
            continue
        dz = z1 - z0
        flat = np.abs(dz) <= 1e-15
        dz = np.where(flat, 1.0, dz)

        def radius(zc, p0=p0, p1=p1, z0=z0, lo=lo, hi=hi, dz=dz, flat=flat, exists=exists):
            inside = (zc >= lo) & (zc <= hi) & exists
            frac = np.where(flat, 0.0, (zc - z0) / dz)
            x = p0[:, 0] + frac * (p1[:, 0] - p0[:, 0])
            y = p0[:, 1] + frac * (p1[:, 1] - p0[:, 1])
            return np.where(inside, np.hypot(x, y), 0.0)

        update((zq >= lo[exists].min()) & (zq <= hi[exists].max()), radius)
    return env


def _ray_radius_at(p, d, zc, upper=None, lower=None, valid=None):
    """Radius of straight rays p + s·d at z (only where z <= upper or z >= lower): (n, N)."""
    dz = np.where(np.abs(d[:, 2]) > 1e-15, d[:, 2], 1e-15)
    s = (zc - p[:, 2]) / dz
    x, y = p[:, 0] + s * d[:, 0], p[:, 1] + s * d[:, 1]
    mask = np.ones(np.broadcast_shapes(zc.shape, s.shape), bool)
    if upper is not None:
        mask &= zc <= upper
    if lower is not None:
        mask &= zc >= lower
    if valid is not None:
        mask &= valid
    return np.where(mask, np.hypot(x, y), 0.0)


__all__ = ["with_clear_semi_diameters", "beam_envelope"]
