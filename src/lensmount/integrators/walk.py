"""The photon walk both integrators share: emit, trace through the optics, deposit, scatter.

One walk, bounce by bounce (pbrt's SPPM photon phase):

1. *Emit* (`emit_photons`): photons first … first+n−1 of the run on the source's emission
   disc, each carrying Φ = A_S / N_pass (E_sun·mm²), its emission numbers keyed by its
   global index (`sampler.Streams`), so a photon is the same whichever pass or batch holds it.
2. *Propagate*: `Tracer.next_event` carries every live photon through the glass to a
   mechanical face, the detector, or out; its random numbers are keyed by
   (seed, purpose, photon, bounce).
3. *Detector*: a photon landing on the detector goes into the film channel of its last
   scattering part (or `direct` / `ghosts`) and under its path signature (`integrators.paths`:
   the faces it scattered at and its ghost reflections, in order), unless the caller gathers its last scattering
   (`gathered`: the bidirectional last-vertex rule; on a glossy finish only a scatter that
   left outside the lobe's core), which counts it instead.
4. *Yield* the bounce (the bidirectional integrator gathers the photons at faces here).
5. *Scatter* at mechanical faces by the face's BSDF, Φ ← Φ · f cos θo / pdf; absorbers (and
   every face when `effects.scatter` is off, or outside its `scatterers`) end the photon. From `roulette_after` scatterings
   on, Russian roulette keeps a photon with q = min(1, Φ / (roulette_level · Φ0)) and divides
   Φ by q (unbiased). At `max_bounces` scatterings the walk stops. With `aim` (the bidirectional
   estimator) a photon on a face ahead of an optical surface draws half its directions toward that
   surface's clear aperture and carries f cos θo over the mixture's density (`scatter_aim`); its
   "absorbed" entry is then Φ_in − Φ_out, negative for a photon that carries more than it brought.

Every flux that leaves the walk is entered in the `EnergyLedger` under its name; a non-finite
BSDF value is an error naming the finish and part, never a silent zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from lensmount.integrators.estimate import BY_ROUTES, EnergyLedger, Film, scattering_tags
from lensmount.integrators.lobe_core import outside_core
from lensmount.integrators.paths import EMPTY, ghost_code
from lensmount.integrators.scatter_aim import (MIXTURE_GAIN, ApertureTargets, disc_directions, drawn_toward,
                                              mixture_weight)
from lensmount.integrators.settings import EstimatorSettings
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import Streams
from lensmount.trace.tracer import DETECTOR, FACE, GONE, Events

DIM_BSDF, DIM_ROULETTE = 0, 2  # Streams dimensions of a bounce (the tracer's Fresnel draws lie far above)


class NonFiniteError(FloatingPointError):
    """A non-finite value where light is carried: names where it came from."""


@dataclass
class Vertices:
    """M photon scatters y1: position, wi (toward the light), normal (photon's side), tag, flux Φ
    arriving, wavelength index, photon id."""

    position: np.ndarray
    wi: np.ndarray
    normal: np.ndarray
    tag: np.ndarray
    flux: np.ndarray
    wavelength: np.ndarray
    id: np.ndarray

    def take(self, rows) -> "Vertices":
        return Vertices(*(getattr(self, k)[rows]
                          for k in ("position", "wi", "normal", "tag", "flux", "wavelength", "id")))


@dataclass
class Bounce:
    """One step of N photons, before they scatter.

    events : the tracer's events for the photons alive at this step
    part : (N,) int32 part (into mesh.parts) of the last scattering vertex before it, -1 = none
    reflections : (N,) Fresnel reflections so far along the path (ghosts)
    scatterings : scattering events so far (the same for every photon of the step)
    signature : (N,) int64 path signature up to the event (`integrators.paths`), not yet the face reached
    came_from : the scatter each photon left before the event (its position, wi, normal, tag), None before the first
    """

    events: Events
    part: np.ndarray
    reflections: np.ndarray
    scatterings: int
    signature: np.ndarray
    came_from: Vertices | None = None


def emit_photons(scene, seed: int, purpose: str, first: int, n: int, n_pass: int) -> RayBatch:
    """Photons first … first+n−1 of the run (ids = global index), each carrying A_S / n_pass."""
    ids = np.arange(first, first + n, dtype=np.int64)
    rays, flux = scene.source.emit(n, Streams(seed, purpose + "/emit", ids))
    rays.id = ids
    rays.weight = np.where(rays.alive, rays.weight * (n / n_pass), 0.0)  # Φ = A_S / N_pass, however batched
    return rays


def photon_walk(scene, tracer, rays: RayBatch, seed: int, purpose: str, settings: EstimatorSettings, film: Film,
                ledger: EnergyLedger, gathered: np.ndarray | None = None,
                aim: ApertureTargets | None = None) -> Iterator[Bounce]:
    """Walk photons `rays` (ids = global photon index) until they die; see the module docstring.

    gathered : (n_tags,) per tag the core of the lobe (direction cosines around the mirror
        direction, `lobe_core.outside_core`) outside which the caller counts the light by
        gathering: a photon whose last scatter there left outside the core is not put on the
        film. 0: all of it is gathered; inf: none. None: every photon is put on the film.
    """
    mesh = scene.mesh
    parts = list(mesh.parts)
    part_of_tag = mesh.part_of_tag() if mesh.tag_table else np.zeros(0, np.int32)
    scatters = scattering_tags(scene)
    surface_index = np.array([s.index for s in scene.optical] + [-1], np.int64)  # [-1]: position -1 → none
    rays = rays.subset(rays.alive & (rays.weight > 0))
    _require_finite(rays.weight, "emitted photon flux", "the source")
    ledger.add("source", rays.weight)
    w0 = rays.weight.copy()  # each photon's emitted flux, the roulette's reference
    part = np.full(len(rays), -1, np.int32)
    by_gather = np.zeros(len(rays), bool)  # the last scatter is the gather's to count
    reflections = np.zeros(len(rays), np.int32)
    signature = np.full(len(rays), EMPTY, np.int64)
    start_normal = None  # photons start in free space; after a scatter, on the face they left
    came_from = None
    for bounce in range(settings.max_bounces + 1):
        if len(rays) == 0:
            return
        streams = Streams(seed, purpose, rays.id, step=bounce)
        ev = tracer.next_event(rays, streams, start_normal)
        reflections = reflections + ev.reflections
        ghost = np.flatnonzero(ev.reflections > 0)
        if len(ghost):
            signature = signature.copy()
            pair = surface_index[ev.ghost_pair[ghost]]
            signature[ghost] = film.paths.extend(signature[ghost], ghost_code(ev.reflections[ghost], pair[:, 0],
                                                                              pair[:, 1]))
        ledger.add("glass", rays.weight - ev.weight)  # Fresnel reflection discarded (ghosts off), bulk absorption
        ledger.add("lost/tracer_guard", ev.weight[ev.lost])
        ledger.add("escaped", ev.weight[(ev.kind == GONE) & ~ev.lost])
        _to_film(film, ledger, ev, part, by_gather, reflections, signature)
        yield Bounce(ev, part, reflections, bounce, signature, came_from)

        face = np.flatnonzero(ev.kind == FACE)
        tag = ev.tag[face]
        w_in = ev.weight[face]
        film.faces.add_lit(tag, w_in)
        if bounce == settings.max_bounces:
            ledger.add("lost/bounce_limit", w_in)
            return
        live = scatters[tag]
        ledger.add_by("absorbed", parts, part_of_tag[tag[~live]], w_in[~live])
        idx, tag, w_in = face[live], tag[live], w_in[live]
        wo, f = _scatter(scene, tag, ev.position[idx], -ev.direction[idx], ev.normal[idx], streams, idx, aim)
        w = w_in * f
        ledger.add_by("absorbed", parts, part_of_tag[tag], w_in - w)
        if bounce + 1 >= settings.roulette_after:
            q = np.minimum(1.0, w / (settings.roulette_level * w0[idx]))
            survive = streams.at(idx, DIM_ROULETTE) < q
            kept = np.where(survive, w / np.where(survive, q, 1.0), 0.0)
            ledger.add("roulette_balance", w - kept)
            w = kept
        ok = w > 0
        keep = idx[ok]
        rays = RayBatch(origin=ev.position[keep], direction=wo[ok], weight=w[ok], wavelength=ev.wavelength[keep],
                        alive=np.ones(len(keep), bool), id=ev.id[keep])
        start_normal = ev.normal[keep]
        came_from = Vertices(ev.position[keep], -ev.direction[keep], start_normal, tag[ok], w_in[ok], ev.wavelength[keep],
                             ev.id[keep])
        part = part_of_tag[tag[ok]].astype(np.int32)
        if gathered is not None:
            core = gathered[tag[ok]]
            by_gather = np.isfinite(core) & outside_core(-ev.direction[keep], wo[ok], ev.normal[keep],
                                                         np.where(np.isfinite(core), core, 0.0))
        else:
            by_gather = np.zeros(len(keep), bool)
        reflections = reflections[keep]
        signature = film.paths.extend(signature[keep], tag[ok])
        w0 = w0[keep]


def gain_bound(scene, settings: EstimatorSettings, aimed: bool = False) -> float:
    """The most flux one photon can bring to the detector per unit of its emitted flux, over every path the walk can
    take (a term's bound: `PassEstimate.term_bound` = this × the heaviest emitted photon); inf when none holds.

    Why it holds: the optics only take flux away (a Fresnel branch is chosen with its probability, bulk absorption
    and discarded reflections lower the weight); a scatter multiplies it by at most its finish's `weight_bound`
    (MIXTURE_GAIN times that where photons are aimed); roulette raises a survivor to at most roulette_level of its
    emitted flux. With every factor at most 1 a path of k ≥ 1 scatters carries at most the largest of them (and an
    unscattered one, counted when `direct` or `ghosts` is on, at most 1), times the detector's largest spectral
    weight. A factor above 1 compounds over the bounces: no useful bound (inf), nor with a mirror in the optics
    (its finish's scatter is the tracer's, `scattering_mirror_tags`)."""
    if any(s.mirror for s in scene.optical):
        return math.inf
    scatters = scattering_tags(scene)
    gains = [scene.bsdf_of_tag[int(t)].weight_bound for t in np.flatnonzero(scatters)]
    g = max(gains, default=0.0) * (MIXTURE_GAIN if aimed else 1.0)
    if g > 1.0:
        return math.inf
    if len(gains) and settings.roulette_after <= settings.max_bounces:
        g = max(g, min(settings.roulette_level, 1.0))
    if scene.effects.direct or scene.effects.ghosts:
        g = 1.0
    response = scene.detector.spectral_weight
    return g * (max(response) if response is not None else 1.0)


def _to_film(film: Film, ledger: EnergyLedger, ev: Events, part, gathered_last, reflections, signature) -> None:
    """Photons on the detector: onto the film by channel, or to the gather's account, or effect off."""
    hit = ev.kind == DETECTOR
    if not hit.any():
        return
    ledger.add("escaped", ev.weight[hit & (ev.pixel < 0)])  # beside the rectangle (test tracers only)
    hit &= ev.pixel >= 0
    channel = film.channel(part, reflections)
    by_gather = hit & gathered_last
    counted = hit & ~by_gather & (channel >= 0)
    by_routes = hit & (channel == BY_ROUTES)  # unscattered: never the gather's
    film.deposit(ev.pixel[counted], ev.weight[counted], ev.wavelength[counted], channel[counted],
                 signature[counted])
    ledger.add_by("detector", film.channels, channel[counted], ev.weight[counted])
    ledger.add_by("detector_gathered", film.channels, channel[by_gather], ev.weight[by_gather])
    ledger.add("detector_ghost_routes", ev.weight[by_routes])
    ledger.add("detector_effect_off", ev.weight[hit & ~by_gather & ~counted & ~by_routes])


def _scatter(scene, tag, position, wi, n, streams: Streams, rows, aim: ApertureTargets | None):
    """Outgoing directions and weights: by the BSDF, or, for a share of the photons `aim` aims (`scatter_aim`),
    toward the next clear aperture, all of those weighted by the mixture's density."""
    aimed = aim.aimed(tag, position) if aim is not None else np.zeros(len(tag), bool)
    if not aimed.any():
        return _sample_bsdf(scene, tag, wi, n, streams, rows)
    a = np.flatnonzero(aimed)
    toward = np.zeros(len(tag), bool)
    toward[a] = drawn_toward(streams, rows[a])
    t, b = np.flatnonzero(toward), np.flatnonzero(~toward)
    wo, f = np.zeros((len(tag), 3)), np.zeros(len(tag))
    wo[b], f[b] = _sample_bsdf(scene, tag[b], wi[b], n[b], streams, rows[b])
    wo[t] = disc_directions(aim, position[t], streams, rows[t])
    f[a] = mixture_weight(scene, aim, tag[a], position[a], wi[a], n[a], wo[a])
    for k in np.unique(tag[a][~np.isfinite(f[a])]):
        _require_finite(f[a][tag[a] == k], "aimed scatter weight (the BSDF's value or density)", _face_name(scene, int(k)))
    return wo, f


def _sample_bsdf(scene, tag, wi, n, streams: Streams, rows):
    """Outgoing directions and weights f·cos/pdf, one vectorised call per finish (not per ray)."""
    m = len(tag)
    wo = np.zeros((m, 3))
    f = np.zeros(m)
    u = np.column_stack([streams.at(rows, DIM_BSDF), streams.at(rows, DIM_BSDF + 1)]) if m else np.zeros((0, 2))
    for t in np.unique(tag):
        sel = tag == t
        o_dir, weight, _ = scene.bsdf_of_tag[int(t)].sample(wi[sel], n[sel], u[sel])
        where = _face_name(scene, int(t))
        _require_finite(weight, "BSDF sample weight", where)
        _require_finite(o_dir, "scattered direction", where)
        wo[sel] = o_dir
        f[sel] = np.maximum(weight, 0.0)  # below the horizon a BSDF returns 0; never negative light
    return wo, f


def _face_name(scene, tag: int) -> str:
    t = scene.mesh.tag_table[tag]
    return f"finish '{t.finish}' on part '{t.part}' (role {t.role}, tag {tag})"


def _require_finite(values: np.ndarray, what: str, where: str) -> None:
    bad = ~np.isfinite(values)
    if bad.any():
        raise NonFiniteError(f"{what} is not finite for {int(np.any(bad.reshape(len(values), -1), axis=1).sum())} "
                             f"photon(s) at {where}")


__all__ = ["photon_walk", "emit_photons", "gain_bound", "Bounce", "NonFiniteError"]
