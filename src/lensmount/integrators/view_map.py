"""Stage 1: backward samples from every pixel → the pass's view map (hit points).

For each pixel, `samples_per_pixel` points x uniform in the pixel and directions ω
from the exit-disc mixture (`exit_sampler`), weight w = cos θ / p(ω). The ray is
traced back through the optics by the tracer (refraction; a Fresnel branch only if
the scene has ghosts on). Where it first meets a mechanical face:

- a *broad* scatterer (Lambertian, or a lobe at least `glossy_threshold_deg` wide):
  store a hit point (position, normal, ω_o = −ω, τ = w·W/S, pixel, tag) and stop;
- anything else (absorber, mirror, narrow lobe): stop without a hit point. Light
  whose last scattering vertex is a mirror or a narrow lobe is counted by the photons
  themselves when they reach the detector (see `bidirectional.py`, "last-vertex rule").

W is the number of wavelengths: each sample picks one uniformly and gathers only
photons of that wavelength.
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.integrators.exit_sampler import ExitDisc, sample_toward_exit
from lensmount.integrators.photon_gather import HitPoints
from lensmount.integrators.radius import initial_radii
from lensmount.integrators.tracing import FACE, DetectorGeometry, next_step
from lensmount.trace.rays import RayBatch


def exit_disc(scene, det: DetectorGeometry, margin: float = 0.05) -> ExitDisc | None:
    """Disc covering the optical surface nearest the detector, in the plane of its point nearest
    the detector, radius = clear semi-diameter · (1 + margin) + 0.5 mm. None without optics."""
    optical = list(getattr(scene, "optical", []) or [])
    if not optical:
        return None
    facing = -1.0 if det.z >= max(s.z_vertex for s in optical) else 1.0
    last = max(optical, key=lambda s: facing * -s.z_vertex)
    h = float(last.clear_semi_diameter)
    sag_edge = float(last.profile.sag(np.array([h * h]))[0])
    if not math.isfinite(sag_edge):
        sag_edge = 0.0
    z_edge = last.z_vertex + sag_edge
    z = max(last.z_vertex, z_edge) if facing < 0 else min(last.z_vertex, z_edge)
    return ExitDisc(z=float(z), radius=h * (1.0 + margin) + 0.5, facing=facing)


def build_view_map(scene, tracer, det: DetectorGeometry, rng: np.random.Generator, *, broad: np.ndarray,
                   half_widths: np.ndarray, radius_scale: float, boundaries=None, samples_per_pixel: int = 1,
                   mixture_c: float = 0.9) -> HitPoints:
    """Trace the backward samples and return the hit points with their pass radii.

    broad : (n_tags,) bool, tags where hit points are made
    half_widths : (n_tags,) face half widths (mm), the cap on r_0
    boundaries : FaceBoundaries for the on-face gather area (None: π r²)
    """
    n_pix = det.nx * det.ny
    s = int(samples_per_pixel)
    pixel = np.repeat(np.arange(n_pix, dtype=np.int64), s)
    n = len(pixel)
    u = rng.random((n, 6))
    x = det.pixel_centres_and_points(pixel, u[:, 0:2])
    disc = exit_disc(scene, det)
    if disc is None:  # no optics: the hemisphere alone (still unbiased)
        disc, mixture_c = ExitDisc(z=det.z - 1.0, radius=1.0), 0.0
    omega, w = sample_toward_exit(x, u[:, 2:5], disc, mixture_c)
    n_wl = len(getattr(scene, "wavelengths_um", [0.5876]))
    wl = np.minimum((u[:, 5] * n_wl).astype(np.int32), n_wl - 1)
    response = getattr(scene.detector, "spectral_weight", None)
    if response is not None:  # the detector's spectral response weights each sample's wavelength
        w = w * np.asarray(response, np.float64)[wl]
    live = w > 0
    rays = RayBatch.make(x[live], omega[live], weight=w[live] * n_wl / s, wavelength=wl[live], ids=pixel[live])
    if len(rays) == 0:
        return HitPoints.empty()
    step = next_step(tracer, rays, rng)
    tag = step.tag
    ok = (step.kind == FACE) & (tag >= 0) & (tag < len(broad))
    ok[ok] &= broad[tag[ok]]
    ok &= (step.weight > 0) & np.isfinite(step.weight)
    if not ok.any():
        return HitPoints.empty()
    pos, nrm, tg = step.position[ok], step.normal[ok], tag[ok]
    radius = initial_radii(pos, tg, half_widths) * float(radius_scale)
    area = boundaries.inside_area(pos, nrm, tg, radius) if boundaries is not None else None
    return HitPoints(position=pos, normal=nrm, omega_o=-step.direction[ok], weight=step.weight[ok],
                     pixel=step.id[ok].astype(np.int64), tag=tg.astype(np.int32),
                     wavelength=step.wavelength[ok].astype(np.int32), radius=radius, area=area)


__all__ = ["exit_disc", "build_view_map"]
