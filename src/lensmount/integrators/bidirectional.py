"""Bidirectional stochastic ray tracing (Zhdanov et al. 2016) as independent progressive passes.

One pass = three phases, as pbrt-v4's SPPM reads:

1. View map (`view_map.build_view_map`): backward samples from every pixel, through
   the optics, to the first broad scatterer they meet → hit points with weight τ,
   outgoing direction ω_o and radius r = r_0 · s_i.
2. Photons: Φ = A_S/N each (units of E_sun), traced forward through the optics; at
   every scattering face they meet they deposit into the hit points on the same face
   within r (`photon_gather.Gatherer`: Σ f Φ / (π r²)), then continue by sampling the
   BSDF, with Russian roulette on the throughput, so inter-reflections count.
3. Update: pixel E_j = Σ_hit τ L_o, split by the part of the hit point's face.

The last-vertex rule (docs/bidirectional.md): every stray path is counted exactly once,
by the kind of its LAST scattering vertex before the detector. Broad (Lambertian, or a
lobe ≥ `glossy_threshold_deg` half width): by the gather at a hit point. Narrow lobe or
mirror: by the photon itself reaching the detector (splatted into its pixel as the
forward estimator does), because a narrow lobe after the optics is nearly specular and
photons follow it efficiently while a density estimate would need an enormous number
of photons in its lobe. Paths with no scattering at all (direct image, pure ghosts)
are counted the same forward way when the scene turns `direct` or `ghosts` on.

Everything random comes from `stream(seed, "view-map", i)` and `stream(seed, "photons", i)`,
so pass i is the same whichever worker runs it.
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.integrators.estimate import PassEstimate
from lensmount.integrators.photon_gather import Gatherer, PhotonHits
from lensmount.integrators.radius import FaceBoundaries, radius_caps
from lensmount.integrators.tracing import DETECTOR, FACE, next_step
from lensmount.integrators.view_map import build_view_map
from lensmount.trace.rays import RayBatch
from lensmount.trace.sampler import stream

GLOSSY_THRESHOLD_DEG = 15.0  # lobes narrower than this (HWHM) are followed by photons, not gathered
MAX_BOUNCES = 64  # scattering events per photon; what survives them is lost_flux
RR_LEVEL = 1e-3  # Russian roulette starts when throughput < RR_LEVEL · initial flux
# Channels of light with no scattering vertex, named as the forward estimator names them.
DIRECT, GHOSTS = "direct", "ghosts"

_CACHE: dict[tuple, tuple] = {}


def classify(bsdf_of_tag, threshold_deg: float = GLOSSY_THRESHOLD_DEG):
    """(broad, scatters) bool arrays per tag: broad gets hit points; scatters continues photons."""
    n = len(bsdf_of_tag)
    broad, scatters = np.zeros(n, bool), np.zeros(n, bool)
    for t, b in enumerate(bsdf_of_tag):
        if b is None or getattr(b, "is_black", False):
            continue
        scatters[t] = True
        width = float(getattr(b, "lobe_half_width_deg", math.inf))
        broad[t] = (not getattr(b, "is_delta", False)) and width >= threshold_deg
    return broad, scatters


def _scene_tables(scene):
    """Per-scene constants (face widths, part table), computed once per process."""
    key = (id(scene), id(scene.mesh))  # the entry holds the scene, so the ids stay unique
    if key not in _CACHE:
        m = scene.mesh
        n_tags = len(m.tag_table)
        hw = radius_caps(m.vertices, m.triangles, m.tags, n_tags)
        boundaries = FaceBoundaries(m.vertices, m.triangles, m.tags, n_tags)
        _CACHE.clear()
        _CACHE[key] = (scene, hw, boundaries, m.part_of_tag(), list(m.parts))
    return _CACHE[key][1:]


def part_names(scene) -> list[str]:
    """The per-part channels a pass reports: the mesh's parts, then `direct` (when the scene
    has direct on) and `ghosts` (when it has ghosts on) — the forward estimator's channels."""
    return (list(scene.mesh.parts) + ([DIRECT] if _effect(scene, "direct") else [])
            + ([GHOSTS] if _effect(scene, "ghosts") else []))


def _effect(scene, name: str) -> bool:
    return bool(getattr(scene.effects, name))


def bidirectional_pass(scene, tracer, n_photons: int, seed: int, pass_index: int, radius_scale: float, *,
                       samples_per_pixel: int = 1, mixture_c: float = 0.5,
                       glossy_threshold_deg: float = GLOSSY_THRESHOLD_DEG, max_bounces: int = MAX_BOUNCES,
                       rr_level: float = RR_LEVEL) -> PassEstimate:
    """One complete, independent pass. Returns the pass's image (ny, nx) of E/E_sun."""
    det = scene.detector
    half_widths, boundaries, part_of_tag, parts = _scene_tables(scene)
    names = part_names(scene)
    n_parts = len(names)
    direct_on, ghosts_on = _effect(scene, "direct"), _effect(scene, "ghosts")
    shape = (det.ny, det.nx)
    n_pix = det.nx * det.ny
    broad, scatters = classify(scene.bsdf_of_tag, glossy_threshold_deg)
    if not _effect(scene, "scatter"):  # every mechanical face absorbs, as in the forward estimator
        broad[:] = False
        scatters[:] = False
    spectral = _spectral_weight(scene)

    # Phase 1: the view map.
    hits = build_view_map(scene, tracer, det, stream(seed, "view-map", pass_index), broad=broad,
                          half_widths=half_widths, radius_scale=radius_scale, boundaries=boundaries,
                          samples_per_pixel=samples_per_pixel, mixture_c=mixture_c, pilot_seed=seed)
    gatherer = Gatherer(hits, scene.bsdf_of_tag)

    # Phase 2: photons.
    rng = stream(seed, "photons", pass_index)
    rays, flux0 = _emit(scene, n_photons, rng)
    splat = np.zeros(n_parts * n_pix)  # Σ Φ for photons counted by the last-vertex rule
    last_part = np.full(len(rays), -1, np.int64)  # -1 until a scatter happens
    reflections = np.zeros(len(rays), np.int64)  # Fresnel reflections so far (ghost paths)
    last_broad = np.zeros(len(rays), bool)
    lost = 0.0
    leaving = None  # normals of the faces the photons leave (None: fresh from the source)
    for _bounce in range(max_bounces):
        if len(rays) == 0:
            break
        step = next_step(tracer, rays, rng, origin_normal=leaving)
        if step.lost is not None and step.lost.any():
            lost += float(np.sum(rays.weight[step.lost & rays.alive]))
        # Photons at the detector: counted here only if their last vertex was narrow/specular.
        at_det = step.kind == DETECTOR
        if step.reflections is not None:
            reflections = reflections + step.reflections
        # Unscattered light: a ghost channel if it reflected at glass (ghosts on), else direct.
        channel = last_part.copy()
        if direct_on:
            channel = np.where(channel < 0, len(parts), channel)
        if ghosts_on:
            channel = np.where((last_part < 0) & (reflections > 0), n_parts - 1, channel)
        count = at_det & ~last_broad & (channel >= 0)
        if count.any():
            pix = det.pixel_of(step.position[count])
            inside = pix >= 0
            idx = channel[count][inside] * n_pix + pix[inside]
            value = step.weight[count][inside] * spectral[step.wavelength[count][inside]]
            splat += np.bincount(idx, weights=value, minlength=n_parts * n_pix)
        # Photons at scattering faces: deposit, then scatter.
        tag = step.tag
        at_face = (step.kind == FACE) & (tag >= 0) & (tag < len(scatters)) & (step.weight > 0)
        at_face[at_face] &= scatters[tag[at_face]]
        if not at_face.any():
            break
        f = np.flatnonzero(at_face)
        gatherer.gather(PhotonHits(step.position[f], step.direction[f], step.normal[f], step.weight[f],
                                   tag[f].astype(np.int32), step.wavelength[f]))
        wo, weight = _scatter(scene.bsdf_of_tag, tag[f], -step.direction[f], step.normal[f], rng)
        weight = step.weight[f] * weight
        # Russian roulette below rr_level of the photon's starting flux; survivors carry 1/q.
        q = np.clip(weight / (rr_level * flux0), 0.0, 1.0)
        survive = (weight > 0) & (rng.random(len(f)) < q)
        weight = np.where(survive, weight / np.where(q > 0, q, 1.0), 0.0)
        keep = survive & np.isfinite(weight)
        f, wo, weight = f[keep], wo[keep], weight[keep]
        last_part = part_of_tag[tag[f]].astype(np.int64)
        last_broad = broad[tag[f]]
        reflections = reflections[f]
        rays = RayBatch(origin=step.position[f].copy(), direction=wo, weight=weight, wavelength=step.wavelength[f].copy(),
                        alive=np.ones(len(f), bool), id=step.id[f].copy())
        leaving = step.normal[f]
    else:  # bounce limit: what is still travelling is the ledger's lost flux
        lost += float(rays.weight[rays.alive].sum()) if len(rays) else 0.0

    # Phase 3: the update — the gather's image plus the photons counted at the detector.
    image_g, parts_g = gatherer.image(shape, part_of_tag, n_parts)
    per_part = parts_g + splat.reshape(n_parts, *shape) / det.pixel_area
    image = image_g + splat.reshape(n_parts, *shape).sum(axis=0) / det.pixel_area
    image = np.where(np.isfinite(image), image, 0.0)
    per_part = np.where(np.isfinite(per_part), per_part, 0.0)
    return PassEstimate(image=image, per_part=per_part, part_names=names, pixel_area_mm2=det.pixel_area,
                        photons=int(n_photons), lost_flux=lost)


def _spectral_weight(scene) -> np.ndarray:
    """(W,) detector spectral response per wavelength index (ones when the detector has none)."""
    n_wl = len(getattr(scene, "wavelengths_um", [0.5876]))
    w = getattr(scene.detector, "spectral_weight", None)
    return np.ones(max(n_wl, 1)) if w is None else np.asarray(w, np.float64)


def _emit(scene, n: int, rng):
    """Photons from the scene's source; weight = Φ (E_sun·mm²). Returns (rays, initial Φ per photon)."""
    rays, flux = scene.source.emit(int(n), rng)
    rays.weight = np.where(rays.alive, rays.weight, 0.0)
    return rays, float(flux)


def _scatter(bsdf_of_tag, tag, wi, n, rng):
    """BSDF-sampled outgoing directions and weights f·cos/pdf, one vectorised call per tag."""
    m = len(tag)
    wo = np.zeros((m, 3))
    weight = np.zeros(m)
    u = rng.random((m, 2))
    for t in np.unique(tag):
        idx = np.flatnonzero(tag == t)
        w_o, w, _pdf = bsdf_of_tag[int(t)].sample(wi[idx], n[idx], u[idx])
        wo[idx] = w_o
        weight[idx] = np.where(np.isfinite(w) & (w > 0), w, 0.0)
    return wo, weight


__all__ = ["bidirectional_pass", "classify", "part_names", "GLOSSY_THRESHOLD_DEG"]
