"""Light on faces the detector sees without optics: each photon connected to the detector (t = 1).

Why. Off the field the sun's image falls on the housing between the last lens and the detector
(at 20° on the reference design: a spot ~1 mm wide at 33 mm from the axis, z 430–480 mm, which the
detector sees straight, no glass between). The gather counts that light only where a hit point
lies within r of the spot, and the housing there gets a handful of backward samples a pass, each
with a large τ (18.85 sr·…): one or two hit points decided a pass (top six held 26–88 % of it),
and a pass read ±220 %. Yet every photon of the spot is there to be counted.

What. The last-vertex rule (bidirectional.py) is split by the last segment. A path whose last
segment runs straight from a broad face to the detector, meeting nothing, is counted by its photon:
at every scattering vertex x on a broad face, one point y is drawn uniformly on the detector and

    Φ_y = Φ · f(ω_i, ω_o) · cos θ_x · cos θ_y / |x − y|² · A_det      (ω_o from x to y)

lands in y's pixel if the segment x → y meets nothing before the detector's front (`Tracer.intersect`).
The expectation over y is Φ's irradiance on the detector by that segment, exactly. A path whose last
segment crosses glass (or any other path the gather sees) stays the gather's: backward rays that meet
a broad face with no optical surface on the way make no hit point (`view_map.build_view_map`,
`connected`). Every path is still counted once. A glossy core the photons count themselves (`gather_cores`) is left out of f here as
there. No kernel, so no kernel bias: these paths leave the ladder of radii flat.
"""

from __future__ import annotations

import numpy as np

from lensmount.integrators.lobe_core import outside_core
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import Streams


def connect_to_detector(scene, tracer, film, position, direction, normal, flux, tag, wavelength, signature,
                        ids, bounce: int, core: np.ndarray, seed: int, purpose: str) -> None:
    """Deposit into `film` the light each photon arriving at a broad face (M,) sends straight to the
    detector from there (module docstring): position, direction (travel, toward the face), normal (on
    the photon's side), flux Φ, tag, wavelength (M,), signature (M,) the path ending with this scatter;
    ids, bounce: the photon's numbers (stream `purpose/connect`, keyed by photon and bounce)."""
    det = scene.detector
    if not len(flux):
        return
    u = Streams(seed, purpose + "/connect", ids, step=int(bounce)).random((len(flux), 2))
    y = np.column_stack([(u[:, 0] - 0.5) * det.width, (u[:, 1] - 0.5) * det.height, np.full(len(flux), det.z)])
    to_y = y - position
    d2 = np.einsum("ij,ij->i", to_y, to_y)
    wo = to_y / np.sqrt(np.maximum(d2, 1e-300))[:, None]
    cos_x, cos_y = np.einsum("ij,ij->i", wo, normal), wo[:, 2]  # the detector faces −z: light arrives along +z
    ok = (cos_x > 0.0) & (cos_y > 0.0) & (d2 > 0.0)
    if not ok.any():
        return
    k = np.flatnonzero(ok)
    seen = tracer.intersect(RayBatch.make(position[k], wo[k]), origin_normal=normal[k])
    k = k[seen.detector & seen.detector_front & ~seen.lost]
    if not len(k):
        return
    value = np.zeros(len(k))
    wi = -direction[k]
    for t in np.unique(tag[k]):
        rows = np.flatnonzero(tag[k] == t)
        bsdf = scene.bsdf_of_tag[int(t)]
        f = np.asarray(bsdf.eval(wi[rows], wo[k][rows], normal[k][rows]), np.float64)
        if core[t] > 0:  # the lobe's core is the photons' own (gather_cores): only the rest here
            f = np.where(outside_core(wi[rows], wo[k][rows], normal[k][rows], float(core[t])), f, 0.0)
        if not np.all(np.isfinite(f)):  # never zeroed: it hides light
            raise FloatingPointError(f"non-finite connection value on face tag {int(t)} for {int(np.sum(~np.isfinite(f)))} "
                                     "photon(s) sent to the detector (the finish's BSDF value is not finite)")
        value[rows] = np.maximum(f, 0.0)
    value *= flux[k] * cos_x[k] * cos_y[k] / d2[k] * (det.width * det.height)
    film.deposit(det.pixel_of(y[k]), value, wavelength[k], film.channel_of_tag[tag[k]], signature[k])


def direct_view(start_direction: np.ndarray, start_weight: np.ndarray, direction: np.ndarray,
                weight: np.ndarray) -> np.ndarray:
    """(N,) the backward rays that reached their face straight from the detector, meeting no optical
    surface: direction and weight unchanged to the bit (a refraction turns the ray, a crossing of glass
    at normal incidence takes its Fresnel transmittance). Their hit points are `connect`'s, not the gather's."""
    return np.all(direction == start_direction, axis=1) & (weight == start_weight)


__all__ = ["connect_to_detector", "direct_view"]
