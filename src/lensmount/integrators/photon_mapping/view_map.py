"""Stage 1: backward samples from every pixel → the pass's view map (hit points).

For each pixel, `samples_per_pixel` points x uniform in the pixel and directions ω
from the exit-disc mixture (`exit_sampler`; with a scattering diaphragm edge, the
pilot-learned edge band of `targets.py`), weight w = cos θ / p(ω). The ray is
traced back through the optics by the tracer (refraction; a Fresnel branch only if
the scene has ghosts on). Where it first meets a mechanical face:

- a *broad* scatterer (Lambertian, or a lobe at least `glossy_threshold_deg` wide):
  store a hit point (position, normal, ω_o = −ω, τ = w·W/S, pixel, tag) and stop;
- anything else (absorber, mirror, narrow lobe): stop without a hit point. Light
  whose last scattering vertex is a mirror or a narrow lobe is counted by the photons
  themselves when they reach the detector (see `bidirectional.py`, "last-vertex rule").

W is the number of wavelengths: each sample picks one uniformly and gathers only
photons of that wavelength.

With a view-map pitch k > 1 a pass draws its samples per block of k × k pixels instead of
per pixel: x uniform in the block, the hit point in the pixel x falls in, τ times the
block's pixel count. Each pass stays unbiased for every pixel and for the total; a pixel is
sampled in about 1/k² of the passes, so the image fills in over passes while the total
(the stray fraction) costs k² fewer backward rays a pass. Since the direct view of broad
faces is counted by connections (`connect`), the total's error hardly depends on how dense
the view map is (CHANGELOG.md, "The view map's pitch").
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.integrators.photon_mapping.connect import direct_view
from lensmount.integrators.exit_sampler import ExitDisc, sample_toward_exit
from lensmount.integrators.photon_mapping.neighbours import kth_distance
from lensmount.integrators.photon_mapping.photon_gather import BIAS_LADDER, HitPoints
from lensmount.integrators.photon_mapping.radius import initial_radii
from lensmount.integrators.photon_mapping.targets import edge_rim, edge_tags, learned_rim, paraxial_trace
from lensmount.integrators.photon_mapping.media import detector_radiance_factor
from lensmount.physics.detector import Detector
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import Streams, ray_streams
from lensmount.trace.tracer import FACE


LEARNED_DISC_SHARE = 0.25  # of c, for the disc when the learned edge target takes the rest
RADIUS_SUBSAMPLE = 128  # on learned-target faces r_0 is the k-th neighbour among ≤ this many hit points
MAX_EDGE_HITS = 16_000  # per pass on learned-target faces; beyond, kept with probability p (τ / p)
VIEW_MAP_CHUNK = 1 << 18  # backward samples traced at once (~0.2 GB of ray arrays, whatever the detector size)


def dense_face_radii(position, tag, faces, cap, radius, k: int = 8, floor_mm: float = 1e-4, cap_mm: float = 5.0):
    """r_0 on the learned target's faces as if they had ≤ RADIUS_SUBSAMPLE hit points (a copy; others kept).

    Why: the learned band puts ~10⁵ hit points on the edge; the k-th-neighbour rule would then
    shrink r_0 to ~15 µm, where a hit point gathers almost no photon and the image stays
    speckle. Measuring the k-th neighbour in a fixed, deterministic subsample (every m-th hit
    point) keeps r_0 at the scale the paraxial rim's few hundred hit points gave (~1 mm).
    """
    r = radius.copy()
    for t in faces:
        idx = np.flatnonzero(tag == t)
        if len(idx) <= RADIUS_SUBSAMPLE:
            continue
        m = -(-len(idx) // RADIUS_SUBSAMPLE)
        sub = position[idx[::m]]
        d = kth_distance(sub, position[idx], min(k + 1, len(sub)))
        limit = min(cap_mm, float(cap[t]) if t < len(cap) else cap_mm)
        r[idx] = np.clip(d, min(floor_mm, limit), limit)
    return r


def exit_disc(scene, det: Detector, margin: float = 0.05) -> ExitDisc | None:
    """Disc covering the optical surface nearest the detector (with mirrors: the last one in the
    sequence, which the detector sees the light come from: a Cassegrain's secondary through the
    primary's hole, not the primary), in the plane of its point nearest the detector, radius =
    clear semi-diameter · (1 + margin) + 0.5 mm. None without optics."""
    optical = list(scene.optical)
    if not optical:
        return None
    facing = -1.0 if det.z >= max(s.z_vertex for s in optical) else 1.0
    if any(s.mirror for s in optical):  # a folded path: the last surface the light crosses, not the nearest
        last = max(optical, key=lambda s: s.index)
    else:
        last = max(optical, key=lambda s: facing * -s.z_vertex)
    h = float(last.clear_semi_diameter)
    if not math.isfinite(h) or h <= 0:
        h = float(last.mechanical_semi_diameter)
    if not math.isfinite(h) or h <= 0:
        return None  # unknown size: the hemisphere alone
    sag_edge = float(last.profile.sag(np.array([h * h]))[0])
    if not math.isfinite(sag_edge):
        sag_edge = 0.0
    z_edge = last.z_vertex + sag_edge
    z = max(last.z_vertex, z_edge) if facing < 0 else min(last.z_vertex, z_edge)
    return ExitDisc(z=float(z), radius=h * (1.0 + margin) + 0.5, facing=facing)


def stop_rim_target(scene, det: Detector, broad: np.ndarray, rel_width: float = 0.02) -> ExitDisc | None:
    """Annulus around the paraxial exit pupil's rim: the diaphragm edge seen from the detector.

    Only when a broad scatterer has role `diaphragm-edge` (case 1): rays aimed at the image
    of the stop rim meet the 50 µm edge ~ 1/(2·rel_width) times more often than rays spread
    over the whole exit disc. The stop rim is the mean radius and z of the edge's vertices;
    its image is a y–nu trace through the optical surfaces behind it (wavelength 0).
    """
    tags = edge_tags(scene, broad)
    optical = sorted(scene.optical, key=lambda s: s.z_vertex)
    if not len(tags) or not optical:
        return None
    z_s, r_s = edge_rim(scene, tags)
    behind = [s for s in optical if s.z_vertex > z_s] if det.z > z_s else []
    if not behind:
        return None
    nu_in = 1.0
    y, nu, z = paraxial_trace(behind, 0.0, nu_in, z_s)  # a ray from the stop's axial point
    n_last = float(np.atleast_1d(behind[-1].n_after)[0])
    if abs(nu) < 1e-12:
        return None
    z_xp = z - y / (nu / n_last)
    r_xp = abs(r_s * nu_in / nu)
    if not (math.isfinite(z_xp) and math.isfinite(r_xp)) or r_xp <= 0 or abs(det.z - z_xp) < 1e-6:
        return None
    return ExitDisc(z=z_xp, radius=r_xp * (1 + rel_width), r_inner=r_xp * (1 - rel_width),
                    facing=-1.0 if det.z > z_xp else 1.0)


def _sample_layout(det: Detector, samples_per_pixel: int, pitch: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(block, sample) of every backward sample of a pass, block-major. A block is `pitch` × `pitch`
    pixels (fewer at the detector's right and top edges); at pitch 1 a block is a pixel."""
    s = int(samples_per_pixel)
    across, up = det.blocks(pitch)
    n_blocks = across * up
    return np.repeat(np.arange(n_blocks, dtype=np.int64), s), np.tile(np.arange(s, dtype=np.int64), n_blocks)


def view_map_streams(seed: int, pass_index: int, det: Detector, samples_per_pixel: int, pitch: int = 1) -> Streams:
    """The numbers of pass `pass_index`'s backward samples, keyed by (seed, pass, block, sample); at
    pitch 1 a block is a pixel."""
    block, sample = _sample_layout(det, samples_per_pixel, pitch)
    return Streams(seed, "view-map", (np.full(len(block), int(pass_index)), block, sample))


def build_view_map(scene, tracer, det: Detector, rng, *, broad: np.ndarray,
                   half_widths: np.ndarray, radius_scale: float, boundaries=None, samples_per_pixel: int = 1,
                   pitch: int = 1, mixture_c: float = 0.9, pilot_seed: int | None = None, neighbours: int = 8,
                   radius_cap_mm: float = 5.0, stats: dict | None = None, faces=None,
                   connected: bool = False) -> HitPoints:
    """Trace the backward samples and return the hit points with their pass radii.

    rng : `view_map_streams(...)` (one stream per sample), or a Generator (keys drawn from it)
    stats : when given, gets `view_map_samples`, `view_map_lost_samples` (backward rays ended by
        the tracer's numerical guards: their pixels see nothing this pass) and `view_map_direct_hit_points`
        (below) added to it
    connected : the photons are connected to the detector (`connect`), so the broad faces a backward ray
        reached straight from the detector, meeting no optical surface (`connect.direct_view`), make no
        hit point: their light is the connections' (each path counted once), and a hit point there would
        cost its radius and areas for nothing (62 % of case 2's)
    faces : when given (a `paths.FaceTally`), gets the projected solid angle (τ / n_wl, sr) of every
        sample at the first face it meets, whatever the finish (the faces the detector sees: critical)

    broad : (n_tags,) bool, tags where hit points are made
    half_widths : (n_tags,) the cap on r_0 per face (`radius.radius_caps`)
    boundaries : FaceBoundaries for the on-face gather area (None: π r²)
    neighbours, radius_cap_mm : r_0 is the `neighbours`-th nearest hit point on the face, at most radius_cap_mm
    pilot_seed : run seed for the learned edge target (`targets.learned_rim`, computed once per
        (scene, tracer, seed)); None: the paraxial rim annulus instead (the estimate is the same).
    """
    s = int(samples_per_pixel)
    block, _ = _sample_layout(det, s, pitch)
    n = len(block)
    paths = ray_streams(rng, n)
    n_wl = len(scene.wavelengths_um)
    disc = exit_disc(scene, det)
    rim = stop_rim_target(scene, det, broad) if disc is not None else None
    # The learned edge window comes from a pilot run, once per (scene, tracer, seed) (targets.learned_rim).
    learned = (learned_rim(scene, tracer, det, broad, pilot_seed, rim)
               if rim is not None and rim.facing == disc.facing and pilot_seed is not None else None)
    if disc is None:  # no optics: the hemisphere alone (still unbiased)
        targets, weights = [ExitDisc(z=det.z - 1.0, radius=1.0)], [0.0]
    elif learned is not None:  # the edge's real window: replaces the paraxial annulus
        targets, weights = [disc, learned], [mixture_c * LEARNED_DISC_SHARE, mixture_c * (1 - LEARNED_DISC_SHARE)]
    elif rim is not None and rim.facing == disc.facing:
        targets, weights = [disc, rim], [mixture_c / 3.0, mixture_c * 2.0 / 3.0]
    else:
        targets, weights = [disc], [mixture_c]
    # Traced in chunks: a sample's numbers and path depend on its own stream only, so the hit
    # points are the same as from one batch, and memory stays bounded at any detector size.
    chunks = [_trace_samples(scene, tracer, det, paths.take(slice(a, a + VIEW_MAP_CHUNK)),
                             block[a:a + VIEW_MAP_CHUNK], pitch, targets, weights, broad, n_wl / s, faces)
              for a in range(0, n, VIEW_MAP_CHUNK)]
    lost = sum(c.pop("lost") for c in chunks)
    if stats is not None:
        stats["view_map_samples"] = stats.get("view_map_samples", 0) + n
        stats["view_map_lost_samples"] = stats.get("view_map_lost_samples", 0) + lost
    hit = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    if not len(hit["tag"]):
        return HitPoints.empty()
    tag, tau = hit["tag"], hit["weight"]
    ok = ~hit["direct"] if connected else np.ones(len(tag), bool)
    if stats is not None:
        stats["view_map_direct_hit_points"] = stats.get("view_map_direct_hit_points", 0) + int(hit["direct"].sum())
    if learned is not None:  # Russian roulette on the edge's hit points: their cost (area, gather) is per point
        on_edge = np.isin(tag, edge_tags(scene, broad)) & ok
        keep_p = min(1.0, MAX_EDGE_HITS / max(int(on_edge.sum()), 1))
        if keep_p < 1.0:
            ok &= ~on_edge | (hit["u_roulette"] < keep_p)
            tau = np.where(on_edge, tau / keep_p, tau)
    pos, nrm, tg = hit["position"][ok], hit["normal"][ok], tag[ok]
    radius = initial_radii(pos, tg, half_widths, k=neighbours, cap_mm=radius_cap_mm)
    if learned is not None:
        radius = dense_face_radii(pos, tg, edge_tags(scene, broad), half_widths, radius, k=neighbours,
                                  cap_mm=radius_cap_mm)
    radius = radius * float(radius_scale)
    area = area_ladder = None
    if boundaries is not None:  # the ladder's first rung is r itself (r · 1.0 == r): its areas are the pass's
        ladder = boundaries.inside_areas(pos, nrm, tg, tuple(m * radius for m in BIAS_LADDER), detector_z=det.z)
        area, area_ladder = ladder[0], np.column_stack(ladder)
    # The detector gets a face's radiance times n_det² / n² (n: the glass a lens edge is seen from inside).
    direction, wavelength = hit["direction"][ok], hit["wavelength"][ok]
    tau = tau[ok] * hit["air"][ok]
    return HitPoints(position=pos, normal=nrm, omega_o=-direction, weight=tau,
                     pixel=hit["pixel"][ok].astype(np.int64), tag=tg.astype(np.int32),
                     wavelength=wavelength.astype(np.int32), radius=radius, area=area,
                     area_ladder=area_ladder)


def _trace_samples(scene, tracer, det: Detector, paths: Streams, block: np.ndarray, pitch: int, targets, weights,
                   broad: np.ndarray, weight_scale: float, faces=None) -> dict:
    """Backward samples of `block` (m,) (pixel blocks of `pitch`) with streams `paths`, traced to their first face: the
    samples that end on a broad scatterer with a positive weight (position, normal, tag, weight,
    direction, air (the 1/n² of a hit from inside glass, `media`), wavelength, pixel, u_roulette) and `lost`,
    the samples the tracer's guards ended.
    faces: as `build_view_map`'s (every sample's first face goes into it here)."""
    m = len(block)
    n_wl = len(scene.wavelengths_um)
    u = paths.random((m, 6))
    x, pixel, block_pixels = det.sample_blocks(block, pitch, u[:, 0:2])
    wl = np.minimum((u[:, 5] * n_wl).astype(np.int32), n_wl - 1)
    omega, w = sample_toward_exit(x, u[:, 2:5], targets, weights, wl)
    response = scene.detector.spectral_weight
    if response is not None:  # the detector's spectral response weights each sample's wavelength
        w = w * np.asarray(response, np.float64)[wl]
    live = w > 0
    rays = RayBatch.make(x[live], omega[live], weight=w[live] * (weight_scale * block_pixels[live]), wavelength=wl[live], ids=pixel[live])
    paths = paths.take(live)
    step = tracer.next_event(rays, paths) if len(rays) else None
    if step is None:
        ok = np.zeros(0, bool)
        step_lost = 0
    else:
        tag = step.tag
        met = np.flatnonzero((step.kind == FACE) & (tag >= 0) & (step.weight > 0) & np.isfinite(step.weight))
        air = np.ones(len(tag))  # the radiance factor of a hit from inside glass, for the faces and the hit points
        air[met] = detector_radiance_factor(scene, step.direction[met], tag[met], step.prim[met], step.wavelength[met])
        if faces is not None:
            # τ carries n_wl (a sample gathers one wavelength's photons): the solid angle is τ / n_wl.
            faces.add_seen(tag[met], step.id[met], step.weight[met] / n_wl * air[met])
        ok = (step.kind == FACE) & (tag >= 0) & (tag < len(broad))
        ok[ok] &= broad[tag[ok]]
        ok &= (step.weight > 0) & np.isfinite(step.weight)
        step_lost = int(step.lost.sum())
    if not ok.any():
        empty = np.zeros(0)
        return dict(position=np.zeros((0, 3)), normal=np.zeros((0, 3)), tag=np.zeros(0, np.int32), weight=empty,
                    direction=np.zeros((0, 3)), air=empty.copy(), wavelength=np.zeros(0, np.int32),
                    pixel=np.zeros(0, np.int64), u_roulette=empty.copy(), direct=np.zeros(0, bool), lost=step_lost)
    direct = direct_view(rays.direction[ok], rays.weight[ok], step.direction[ok], step.weight[ok])
    return dict(position=step.position[ok], normal=step.normal[ok], tag=step.tag[ok], weight=step.weight[ok],
                direction=step.direction[ok], air=air[ok], wavelength=step.wavelength[ok],
                pixel=step.id[ok], u_roulette=paths.at(np.flatnonzero(ok), 6), direct=direct, lost=step_lost)


__all__ = ["exit_disc", "build_view_map", "view_map_streams"]
