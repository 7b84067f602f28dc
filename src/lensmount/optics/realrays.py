"""Sequential real-ray trace through a prescription, vectorised over ray batches (float64).

Every surface runs the same short pipeline (as optiland does):
localise -> intersect (`Profile.intersect`) -> clip at the clear semi-diameter ->
refract (vector Snell) or reflect (a mirror) -> record. A ray that misses a surface, falls outside its
clear aperture, suffers total internal reflection or cannot reach the image
plane is *vignetted*: it is marked, keeps its last valid point and direction
(so no NaN ever appears) and is carried along without further effect.

Ray aiming (`aim`): for an object at infinity a field is a direction; for a finite
object it is a point of the object plane, and each ray's direction is the line from
that point to its launch point. Rays are launched on the plane z = 0
(surface 1's vertex plane; intersections with negative
ray parameter are fine in a sequential trace) and their launch points are solved
by Newton's method so that each ray crosses the *stop* at the requested
normalised pupil coordinate times the stop semi-diameter (real-ray aiming, as
Zemax's "ray aiming: real"). The stop semi-diameter is where the real on-axis ray
through the rim of the entrance pupil (EPD/2) crosses the stop, as OpticStudio sizes
an automatic stop, so the real on-axis beam enters at exactly the designed EPD: the
paraxial height differs from it by the spherical aberration of the lenses in front of
the stop (a strong asphere there: 6.81 mm against 9.15 mm). A lens with
telecentric object space is aimed as Zemax does: chief rays parallel to the axis, the
pupil in direction cosines of the object-space NA, no stop involved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.optics.paraxial import indices, marginal_heights, marginal_start, paraxial
from lensmount.optics.prescription import Prescription
from lensmount.optics.profiles import Profile
from lensmount.optics.snell import reflect, refract

CLIP_REL_TOL = 1e-9  # a ray exactly on an automatic clear aperture passes
_AIM_STEPS = 12
_AIM_TOL = 1e-10  # mm at the stop
_FD_STEP = 1e-4  # mm, finite-difference step for the aiming Jacobian
_AIM_BACKTRACK = 8  # halvings of a Newton step before the ray keeps its last good start


@dataclass
class RealRays:
    """The result of a sequential trace of N rays through S surfaces.

    points : (S+1, N, 3) float64, mm, assembly frame; [i] the hit on surface i
        (0-based), [S] the hit on the image plane.
    directions : (S+1, N, 3) float64 unit vectors; [i] after refraction at surface i,
        [S] equals [S-1].
    vignetted : (N,) bool.
    vignetted_at : (N,) int, 0-based surface where the ray stopped, S for the image
        plane, -1 if it arrived.
    origins, start_directions : (N, 3) the rays as launched.
    wavelength_um : float.
    """

    points: np.ndarray
    directions: np.ndarray
    vignetted: np.ndarray
    vignetted_at: np.ndarray
    origins: np.ndarray
    start_directions: np.ndarray
    wavelength_um: float

    @property
    def intensity(self) -> np.ndarray:
        """(N,) 1 for rays that arrive, 0 for vignetted ones."""
        return np.where(self.vignetted, 0.0, 1.0)

    @property
    def image_points(self) -> np.ndarray:
        """(N, 3) hits on the image plane (frozen last point for vignetted rays)."""
        return self.points[-1]

    def heights(self) -> np.ndarray:
        """(S+1, N) radial distance from the axis of every recorded point."""
        return np.hypot(self.points[..., 0], self.points[..., 1])


def trace(prescription: Prescription, origins, directions, wavelength_um: float | None = None, *,
          clip: bool = True, n_surfaces: int | None = None, image_z: float | None = None) -> RealRays:
    """Trace rays sequentially through the surfaces and onto the image plane.

    Args:
        prescription: the lens.
        origins: (N, 3) ray start points, mm, assembly frame (in front of surface 1's
            vertex plane, or on it).
        directions: (N, 3) directions (normalised here), in the object-space medium (air).
        wavelength_um: defaults to the primary wavelength.
        clip: vignette rays outside each surface's clear semi-diameter (surfaces
            without one never clip). Defaults to True.
        n_surfaces: trace only the first n surfaces (then `points` has n+1 entries, the
            last being the image-plane hit of the partly traced rays). Defaults to all.
        image_z: image plane z, defaults to `prescription.image_z`.
    """
    wl = prescription.primary_wavelength_um if wavelength_um is None else float(wavelength_um)
    o = np.array(origins, dtype=np.float64, ndmin=2).reshape(-1, 3)
    d = np.array(directions, dtype=np.float64, ndmin=2).reshape(-1, 3)
    # Lanes with a non-finite or zero-length start are dead from the outset (no NaN downstream).
    bad = ~(np.isfinite(o).all(axis=1) & np.isfinite(d).all(axis=1)) | ~(np.abs(d).sum(axis=1) > 0.0)
    o = np.where(bad[:, None], 0.0, o)
    d = np.where(bad[:, None], [0.0, 0.0, 1.0], d)
    d = d / _safe_norm(d)[:, None]
    n_rays = len(o)
    surfaces = prescription.surfaces[: len(prescription.surfaces) if n_surfaces is None else n_surfaces]
    nsurf = len(surfaces)
    n = indices(prescription, wl)
    z_vertex = prescription.vertex_z

    points = np.empty((nsurf + 1, n_rays, 3))
    dirs = np.empty((nsurf + 1, n_rays, 3))
    alive = ~bad
    stopped_at = np.where(bad, 0, -1).astype(np.int64)
    p, cur = o.copy(), d.copy()

    frames = prescription.frames   # () on one axis: the vertices at z_vertex, no rotation
    for i, surface in enumerate(surfaces):
        profile = Profile.of(surface)
        # localise
        if frames:
            local, cur_local = frames[i].to_local(p, cur)
        else:
            local, cur_local = p - np.array([0.0, 0.0, z_vertex[i]]), cur
        # intersect
        t = profile.intersect(local, cur_local)
        hit_ok = np.isfinite(t)
        t = np.where(hit_ok, t, 0.0)
        q = local + t[:, None] * cur_local
        # clip
        ok = alive & hit_ok
        if clip and surface.clear_semi_diameter is not None:
            limit = surface.clear_semi_diameter * (1.0 + CLIP_REL_TOL) + CLIP_REL_TOL
            ok &= q[:, 0] ** 2 + q[:, 1] ** 2 <= limit * limit
        # refract, or reflect at a mirror
        if surface.mirror:
            new_dir = reflect(cur_local, profile.normal(q))
            new_dir = new_dir / _safe_norm(new_dir)[:, None]
        else:
            new_dir, tir, _, _ = refract(cur_local, profile.normal(q), np.full(len(cur), n[i] / n[i + 1]))
            ok &= ~tir
        # record (vignetted lanes keep their last valid point and direction)
        newly = alive & ~ok
        stopped_at[newly] = i
        alive = ok
        # globalise
        if frames:
            q_global, new_dir = frames[i].to_global(q, new_dir)
        else:
            q_global = q + np.array([0.0, 0.0, z_vertex[i]])
        p = np.where(alive[:, None], q_global, p)
        cur = np.where(alive[:, None], new_dir, cur)
        points[i], dirs[i] = p, cur

    # image plane (off one axis: the z = image_z - its vertex plane of the image frame)
    z_img = prescription.image_z if image_z is None else float(image_z)
    if frames:
        p_img, cur_img = frames[-1].to_local(p, cur)
        z_img -= prescription.image_z
    else:
        p_img, cur_img = p, cur
    forward = cur_img[:, 2] * (prescription.travel[nsurf - 1] if nsurf else 1) > 1e-12
    t = np.where(forward, (z_img - p_img[:, 2]) / np.where(forward, cur_img[:, 2], 1.0), 0.0)
    ok = alive & forward
    stopped_at[alive & ~ok] = nsurf
    alive = ok
    points[nsurf] = np.where(alive[:, None], p + t[:, None] * cur, p)
    dirs[nsurf] = cur
    return RealRays(points, dirs, ~alive, stopped_at, o, d, wl)


# ----------------------------------------------------------------------------- aiming


def field_direction(field_deg) -> np.ndarray:
    """(F, 3) unit directions of collimated beams tilted by field angles (deg) in the y-z plane."""
    a = np.radians(np.atleast_1d(np.asarray(field_deg, dtype=np.float64)))
    return np.stack([np.zeros_like(a), np.sin(a), np.cos(a)], axis=1)


def axial_rim_ray(prescription: Prescription, wavelength_um: float | None = None) -> RealRays:
    """The real on-axis ray through the rim of the paraxial entrance pupil (N = 1, clip off): at
    infinity parallel to the axis at EPD/2, from a finite object from the axial object point
    towards the pupil's rim (`paraxial.marginal_start`). Its first point (`origins`) is in object
    space: 1 mm before surface 1's vertex plane, or the object point."""
    par = paraxial(prescription, wavelength_um)
    y1, u = marginal_start(prescription, par.epd, par.entrance_pupil_z)
    if prescription.finite_object:
        origin, direction = [0.0, 0.0, -prescription.object_distance], [0.0, y1, prescription.object_distance]
    else:
        origin, direction = [0.0, y1, -1.0], [0.0, 0.0, 1.0]
    return trace(prescription, np.array([origin]), np.array([direction]), wavelength_um, clip=False)


def stop_semi_diameter(prescription: Prescription, wavelength_um: float | None = None) -> float:
    """Stop semi-diameter: the height at which the real on-axis ray through the rim of the
    entrance pupil crosses the stop (`axial_rim_ray`), as OpticStudio sizes an automatic stop
    (its DIAM: 9.1499 mm for Thorlabs ACL2520-A, whose paraxial height is 6.81 mm). Where that
    ray is lost before the stop (it misses a surface, or is totally reflected) the paraxial
    height stands, and the real beam's trace names the surface."""
    par = paraxial(prescription, wavelength_um)
    stop = prescription.stop_index
    rim = axial_rim_ray(prescription, wavelength_um)
    at = int(rim.vignetted_at[0])
    if 0 <= at <= stop:
        return par.stop_semi_diameter
    return float(np.hypot(*rim.points[stop, 0, :2]))


def aim(prescription: Prescription, field_deg, pupil_xy, wavelength_um: float | None = None,
        stop_radius: float | None = None, at_z: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Launch rays so that they cross the stop at pupil_xy · stop semi-diameter.

    Args:
        field_deg: (F,) field angles, degrees, in the y-z plane; for a finite object,
            object heights in mm (`Prescription.field_values`).
        pupil_xy: (P, 2) normalised pupil coordinates (unit disc = full aperture), the same for
            every field, or (F, P, 2): one set per field (a vignetted beam).
        stop_radius: stop semi-diameter, mm; defaults to `stop_semi_diameter` at the
            primary wavelength (the diaphragm is one size for every colour).
        at_z: aim at the plane z = at_z (where each ray's path first crosses it) instead of
            the stop surface: a diaphragm's land, which cannot lie on a curved stop face.
    Returns:
        origins (F·P, 3) on the plane z = 0 and directions (F·P, 3), field-major
        (ray f·P + p is field f, pupil point p). Rays the solver cannot place (they
        miss a surface before the stop) keep their paraxially aimed start.
    """
    wl = prescription.primary_wavelength_um if wavelength_um is None else float(wavelength_um)
    fields = np.atleast_1d(np.asarray(field_deg, dtype=np.float64))
    pupil = np.asarray(pupil_xy, dtype=np.float64)
    n_f = len(fields)
    n_p = pupil.shape[1] if pupil.ndim == 3 else len(pupil.reshape(-1, 2))
    pupil = np.broadcast_to(pupil.reshape(-1, n_p, 2), (n_f, n_p, 2)).reshape(-1, 2)  # per ray, field-major
    par = paraxial(prescription, wl)
    if prescription.finite_object:
        # a field is the object point (0, -h, -distance): a positive height images upward-going, like +angle
        source = np.column_stack([np.zeros(n_f), -fields, np.full(n_f, -prescription.object_distance)])
        source = np.repeat(source, n_p, axis=0)
    else:
        source = None
        d = np.repeat(field_direction(fields), n_p, axis=0)
    if prescription.object_telecentric:
        return _telecentric(prescription, source, pupil)
    stop = prescription.stop_index
    r_stop = stop_semi_diameter(prescription) if stop_radius is None else float(stop_radius)
    target = pupil * r_stop

    def directions(xy_, rows=slice(None)):
        if source is None:
            return d[rows]
        v = np.column_stack([xy_, np.zeros(len(xy_))]) - source[rows]
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    # Paraxial start: through the entrance pupil point, back-projected onto z = 0
    # (finite object: the stop's paraxial image seen from the object, scaled to z = 0).
    if source is None:
        ep = pupil * par.epd / 2.0
        ep3 = np.column_stack([ep, np.full(len(ep), par.entrance_pupil_z)])
        xy = (ep3 - d * (par.entrance_pupil_z / d[:, 2])[:, None])[:, :2].copy()
    else:
        # the line from the object point to the entrance pupil point, at z = 0
        dist, ep_z = prescription.object_distance, par.entrance_pupil_z
        y1 = abs(float(marginal_heights(prescription, wl)[0]))  # axial marginal ray height at z = 0
        xy = pupil * y1 + source[:, :2] * (ep_z / (dist + ep_z))

    def at_stop(xy_, rows):
        o = np.column_stack([xy_, np.zeros(len(xy_))])
        if at_z is not None:
            return plane_crossing(trace(prescription, o, directions(xy_, rows), wl, clip=False), at_z)
        r = trace(prescription, o, directions(xy_, rows), wl, clip=False, n_surfaces=stop + 1)
        ok = (r.vignetted_at == -1) | (r.vignetted_at > stop)
        return r.points[stop, :, :2], ok

    s0, ok0 = at_stop(xy, np.arange(len(xy)))
    stuck = np.zeros(len(xy), bool)  # rays no Newton step (or fraction of one) can improve
    for _ in range(_AIM_STEPS):
        res = s0 - target
        rows = np.flatnonzero(ok0 & ~stuck & ~(np.hypot(res[:, 0], res[:, 1]) < _AIM_TOL))
        if len(rows) == 0:
            break
        x, r0 = xy[rows], res[rows]
        sx, okx = at_stop(x + [_FD_STEP, 0.0], rows)
        sy, oky = at_stop(x + [0.0, _FD_STEP], rows)
        j11, j21 = (sx[:, 0] - s0[rows, 0]) / _FD_STEP, (sx[:, 1] - s0[rows, 1]) / _FD_STEP
        j12, j22 = (sy[:, 0] - s0[rows, 0]) / _FD_STEP, (sy[:, 1] - s0[rows, 1]) / _FD_STEP
        det = j11 * j22 - j12 * j21
        pending = okx & oky & (np.abs(det) > 1e-12)
        stuck[rows[~pending]] = True
        safe_det = np.where(pending, det, 1.0)
        step = np.column_stack([(j22 * r0[:, 0] - j12 * r0[:, 1]) / safe_det,
                                (-j21 * r0[:, 0] + j11 * r0[:, 1]) / safe_det])
        # Halve a step that would throw the ray off a surface before the stop: an undamped
        # Newton step can land far outside the lens, and the ray would then "miss" surface 1
        # although the surface that really limits the beam lies further on.
        for _half in range(_AIM_BACKTRACK):
            idx = np.flatnonzero(pending)
            s_t, ok_t = at_stop(x[idx] - step[idx], rows[idx])
            took = idx[ok_t]
            xy[rows[took]] = x[took] - step[took]
            s0[rows[took]] = s_t[ok_t]
            pending[took] = False
            if not pending.any():
                break
            step = 0.5 * step
        stuck[rows[pending]] = True
    origins = np.column_stack([xy, np.zeros(len(xy))])
    return origins, directions(xy)


def plane_crossing(rays: RealRays, z: float) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) x, y where each ray's path first crosses the plane z, and (N,) whether it reaches it:
    the launch line (extended back in object space), the legs between the surfaces the ray
    reached, and, for a ray that arrived, its line on beyond the image plane."""
    pts, n = rays.points, rays.points.shape[1]
    xy, found = np.zeros((n, 2)), np.zeros(n, bool)

    def cross(sel, a, b):
        """Rays `sel` on the segment a -> b (N, 3) whose z range holds z."""
        dz = b[:, 2] - a[:, 2]
        hit = sel & ~found & (np.abs(dz) > 1e-15) & (np.minimum(a[:, 2], b[:, 2]) <= z) & (np.maximum(a[:, 2], b[:, 2]) >= z)
        t = (z - a[hit, 2]) / dz[hit]
        xy[hit] = a[hit, :2] + t[:, None] * (b[hit, :2] - a[hit, :2])
        found[hit] = True

    # in front of surface 1: the launch line, as far back as it goes
    d0 = rays.start_directions
    back = pts[0] - d0 * (np.maximum(pts[0][:, 2] - z, 0.0) / np.where(d0[:, 2] > 1e-15, d0[:, 2], 1.0) + 1.0)[:, None]
    cross(d0[:, 2] > 1e-15, back, pts[0])
    last_ok = np.where(rays.vignetted_at < 0, len(pts) - 1, rays.vignetted_at)   # legs j < last_ok exist
    for j in range(len(pts) - 1):
        cross(j < last_ok, pts[j], pts[j + 1])
    arrived = rays.vignetted_at < 0
    d = rays.directions[-1]
    ahead = pts[-1] + d * (np.maximum(z - pts[-1][:, 2], 0.0) / np.where(d[:, 2] > 1e-15, d[:, 2], 1.0) + 1.0)[:, None]
    cross(arrived & (d[:, 2] > 1e-15), pts[-1], ahead)
    return xy, found


def _telecentric(prescription: Prescription, source: np.ndarray, pupil: np.ndarray):
    """Telecentric object space: a pupil point (x, y) is the direction cosines NA·(x, y) from the
    object point (the chief ray, (0, 0), parallel to the axis), as Zemax aims such a lens."""
    na = float(prescription.aperture.value)
    lm = na * pupil
    d = np.column_stack([lm, np.sqrt(np.clip(1.0 - (lm * lm).sum(axis=1), 0.0, None))])
    origins = source + d * (prescription.object_distance / d[:, 2])[:, None]
    return origins, d


def pupil_rings(rings: int, spokes: int, center: bool = True, half: bool = False) -> np.ndarray:
    """(P, 2) normalised pupil points: rings at radii k/rings (k = 1..rings), `spokes` azimuths each.

    half=True keeps the x >= 0 half (spokes/2 + 1 azimuths from -90 to +90 deg, both ends
    included): enough for meridional fields, whose beams are mirror-symmetric in x.
    """
    if half:
        phi = np.linspace(-0.5 * np.pi, 0.5 * np.pi, spokes // 2 + 1)
    else:
        phi = 2.0 * np.pi * np.arange(spokes) / spokes
    pts = [np.zeros((1, 2))] if center else []
    for k in range(1, rings + 1):
        rho = k / rings
        pts.append(np.column_stack([rho * np.cos(phi), rho * np.sin(phi)]))
    return np.concatenate(pts)


def chief_ray(prescription: Prescription, field_deg, wavelength_um: float | None = None, **kw) -> RealRays:
    """Rays through the stop centre, one per field angle (N = F)."""
    o, d = aim(prescription, field_deg, [[0.0, 0.0]], wavelength_um)
    return trace(prescription, o, d, wavelength_um, **kw)


def image_height(p: Prescription) -> float:
    """Height of the largest field's real chief ray on the image plane, mm (0 for an on-axis lens).
    The largest field is an angle, or for a finite object the largest object height."""
    field = max((abs(f) for f in p.field_values), default=0.0)
    if field <= 0.0:
        return 0.0
    h = float(np.abs(chief_ray(p, field).image_points[..., 1]).max())
    return h if math.isfinite(h) else 0.0


def marginal_ray(prescription: Prescription, field_deg=0.0, wavelength_um: float | None = None,
                 pupil_y: float = 1.0, **kw) -> RealRays:
    """Rays through the stop edge at normalised pupil y = `pupil_y` (upper rim), one per field."""
    o, d = aim(prescription, field_deg, [[0.0, pupil_y]], wavelength_um)
    return trace(prescription, o, d, wavelength_um, **kw)


@dataclass
class Spot:
    """Spot diagram data for one field and wavelength.

    x, y : (M,) image-plane coordinates (mm) of the rays that arrived.
    chief_x, chief_y : chief ray at the image plane.
    rms_radius : RMS distance from the centroid, mm.
    transmitted : fraction of the launched rays that arrived.
    """

    x: np.ndarray
    y: np.ndarray
    chief_x: float
    chief_y: float
    rms_radius: float
    transmitted: float


def spot(prescription: Prescription, field_deg: float, wavelength_um: float | None = None,
         rings: int = 8, spokes: int = 24, image_z: float | None = None) -> Spot:
    """Spot diagram on the image plane for one field (polar pupil grid, rings x spokes)."""
    pupil = pupil_rings(rings, spokes)
    o, d = aim(prescription, [field_deg], pupil, wavelength_um)
    r = trace(prescription, o, d, wavelength_um, image_z=image_z)
    arrived = ~r.vignetted
    x, y = r.image_points[arrived, 0], r.image_points[arrived, 1]
    chief = r.image_points[0]  # pupil point 0 is the centre
    if len(x):
        rms = float(np.sqrt(np.mean((x - x.mean()) ** 2 + (y - y.mean()) ** 2)))
    else:
        rms = 0.0
    return Spot(x, y, float(chief[0]), float(chief[1]), rms, float(arrived.mean()))


def _safe_norm(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1)
    return np.where(n > 0.0, n, 1.0)


__all__ = ["RealRays", "trace", "aim", "plane_crossing", "field_direction", "axial_rim_ray", "stop_semi_diameter",
           "pupil_rings", "chief_ray", "image_height", "marginal_ray", "Spot", "spot"]
