"""Forward light tracing: the unbiased, slow reference the bidirectional estimator is checked against.

One pass, in three phases per bounce (as pbrt's SPPM reads):

1. *Emit.* N photons on the source's emission disc, each carrying Φ = A_S / N (E_sun·mm²).
2. *Propagate.* `Tracer.next_event` carries them through the glass (refraction, TIR,
   Fresnel) to a mechanical face, the detector, or out of the assembly.
3. *Deposit or scatter.* On the detector a photon deposits Φ / A_pixel into its pixel
   (E/E_sun), in the channel of the part where it last scattered. A photon that never
   scattered counts only when `effects.direct` is on (channel `direct`), or when ghosts are
   on and it took a Fresnel reflection (channel `ghosts`). On a mechanical face it samples
   the face's BSDF, Φ ← Φ · f cos θo / pdf, and goes on; absorbers (and every face when
   `effects.scatter` is off) end it. After `ROULETTE_AFTER` scattering events Russian
   roulette keeps a photon with probability q = min(1, Φ / Φ0) and divides Φ by q, which keeps
   the estimate unbiased. Paths still alive after `max_bounces` scatterings are dropped and
   their flux reported in `lost_flux`, as is the flux of rays the tracer's guards ended.

The same walk (`light_paths`) serves the furnace test: it yields every bounce's events.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from lensmount.integrators.estimate import PassEstimate
from lensmount.trace.rays import RayBatch
from lensmount.trace.sampler import stream
from lensmount.trace.tracer import DETECTOR, FACE, Events

ROULETTE_AFTER = 3
MAX_BOUNCES = 64
BATCH = 200_000  # photons per chunk: bounds memory, not the result (streams are per chunk)


@dataclass
class Bounce:
    """One step of N light paths.

    events : the tracer's events for the rays that were alive at this step
    part : (N,) int32 part index (into mesh.parts) of the last scattering event before it, -1 = none
    reflections : (N,) int32 Fresnel reflections so far along the path (ghosts)
    scatterings : int, scattering events so far (same for all rays of the step)
    """

    events: Events
    part: np.ndarray
    reflections: np.ndarray
    scatterings: int


@dataclass
class WalkLedger:
    """Flux bookkeeping of a walk: lost to guards and bounce limit, and killed by roulette."""

    lost_flux: float = 0.0


def light_paths(scene, tracer, rays: RayBatch, rng: np.random.Generator, *, max_bounces: int = MAX_BOUNCES,
                ledger: WalkLedger | None = None) -> Iterator[Bounce]:
    """Walk photons until they die; yield each bounce's events (before scattering at them).

    Scattering uses the face's BSDF; Russian roulette after ROULETTE_AFTER scatterings.
    """
    ledger = ledger if ledger is not None else WalkLedger()
    part_of_tag = scene.mesh.part_of_tag() if scene.mesh.tag_table else np.zeros(0, np.int32)
    bsdfs = scene.bsdf_of_tag
    scatter_on = bool(scene.effects.scatter)
    rays = rays.subset(rays.alive & (rays.weight > 0))
    w0 = rays.weight.copy()  # each photon's starting flux, the roulette's reference
    part = np.full(len(rays), -1, np.int32)
    reflections = np.zeros(len(rays), np.int32)
    start_normal = None  # photons start in free space; after a scatter, on the face they left
    for bounce in range(max_bounces + 1):
        if len(rays) == 0:
            return
        ev = tracer.next_event(rays, rng, start_normal)
        reflections = reflections + ev.reflections
        ledger.lost_flux += float(ev.weight[ev.lost].sum())
        yield Bounce(ev, part, reflections, bounce)
        face = ev.kind == FACE
        if not scatter_on or not face.any() or bounce == max_bounces:
            if bounce == max_bounces:
                ledger.lost_flux += float(ev.weight[face].sum())
            return
        idx = np.flatnonzero(face)
        wi = -ev.direction[idx]
        n = ev.normal[idx]
        tag = ev.tag[idx]
        wo = np.zeros((len(idx), 3))
        f = np.zeros(len(idx))
        u = rng.random((len(idx), 2))
        for t in np.unique(tag):  # a loop over finishes, not over rays
            bsdf = bsdfs[t] if 0 <= t < len(bsdfs) else None
            if bsdf is None or getattr(bsdf, "is_black", False):
                continue
            sel = tag == t
            o_dir, weight, _ = bsdf.sample(wi[sel], n[sel], u[sel])
            wo[sel] = o_dir
            f[sel] = np.where(np.isfinite(weight) & (weight > 0), weight, 0.0)
        w = ev.weight[idx] * f
        ok = (w > 0) & np.all(np.isfinite(wo), axis=1)
        if bounce + 1 >= ROULETTE_AFTER:
            q = np.minimum(1.0, w / np.maximum(w0[idx], 1e-300))
            survive = rng.random(len(idx)) < q
            w = np.where(survive, w / np.where(q > 0, q, 1.0), 0.0)
            ok &= survive
        keep = idx[ok]
        rays = RayBatch(origin=ev.position[keep], direction=wo[ok], weight=w[ok], wavelength=ev.wavelength[keep],
                        alive=np.ones(len(keep), bool), id=ev.id[keep])
        start_normal = n[ok]
        part = part_of_tag[tag[ok]].astype(np.int32)
        reflections = reflections[keep]
        w0 = w0[keep]


def forward_pass(scene, tracer, n_photons: int, seed: int, pass_index: int, *, max_bounces: int = MAX_BOUNCES,
                 batch: int = BATCH) -> PassEstimate:
    """One independent pass of forward light tracing (see the module docstring)."""
    det = scene.detector
    parts = list(scene.mesh.parts)
    names = parts + (["direct"] if scene.effects.direct else []) + (["ghosts"] if scene.effects.ghosts else [])
    per_part = np.zeros((len(names), det.ny, det.nx))
    ledger = WalkLedger()
    done = 0
    chunk = 0
    while done < n_photons:
        n = min(batch, n_photons - done)
        rng = stream(seed, "forward", pass_index * 1_000_003 + chunk)
        rays, _ = scene.source.emit(n, rng)
        rays.weight *= n / n_photons  # Φ = A_S / N_pass: chunking must not change a photon's flux
        for step in light_paths(scene, tracer, rays, rng, max_bounces=max_bounces, ledger=ledger):
            ev = step.events
            hit = (ev.kind == DETECTOR) & (ev.pixel >= 0)
            if not hit.any():
                continue
            channel = step.part.copy()
            if scene.effects.direct:
                channel = np.where(channel < 0, len(parts), channel)
            if scene.effects.ghosts:
                ghost = (step.part < 0) & (step.reflections > 0)
                channel = np.where(ghost, len(names) - 1, channel)
            hit &= channel >= 0
            for c in np.unique(channel[hit]):
                sel = hit & (channel == c)
                per_part[c] += det.deposit(ev.position[sel], ev.weight[sel], ev.wavelength[sel])
        done += n
        chunk += 1
    image = per_part.sum(axis=0)
    return PassEstimate(image=image, per_part=per_part, part_names=names, pixel_area_mm2=det.pixel_area,
                        photons=int(n_photons), lost_flux=float(ledger.lost_flux))


__all__ = ["forward_pass", "light_paths", "Bounce", "WalkLedger", "ROULETTE_AFTER", "MAX_BOUNCES"]
