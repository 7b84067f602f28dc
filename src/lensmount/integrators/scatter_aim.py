"""Photons' scatter aimed at the clear aperture they must cross next on the way to the detector.

Why. Past the field, stray light scatters at least once in front of the stop, and what reaches the
detector must then cross the optics behind that point. A Lambertian scatter sends a photon into that
opening a few times in a hundred: from spacer-2's front bore on the reference design 0.77 % of the
directions get past the stop (z > 200 mm), 0.009 % reach the housing within 30 mm of the detector.
At 20° about 5 photons of a pass's 2 × 10⁴ met the housing, and the one of them that landed by the
detector carried 89 % of the pass: a pass was a count of a few rare events (±60 % a pass).

What. A photon scattering on a mechanical face whose lobe the gather counts whole (Lambertian, or a
lobe at least `glossy_threshold_deg` wide), at a point in front of an optical surface, is aimed at
the first surface beyond it toward the detector: the disc over that surface's clear aperture, in
the plane of the surface's nearer extreme, radius the clear semi-diameter × (1 + MARGIN) + 0.5 mm
(the view map's exit disc, `view_map.exit_disc`). Its direction is drawn with probability c =
`AIMED_SHARE` toward a uniform point q of the disc, from the BSDF otherwise, and it carries

    f cos θ / ((1 − c) p_bsdf(ω) + c p_disc(ω)),   p_disc(ω) = |q − x|² / (A cos θ_q)   (q: where ω crosses)

the mixture's own density whichever way the direction came (one-sample MIS, the balance heuristic).
So the estimate is unbiased whatever the disc (it only moves samples), and a photon carries at most
1 / (1 − c) times its unaimed weight. Only the direction is aimed: what the photon meets on its way
(a spacer's lip, the glass, the stop) is traced as before. The target is a function of the point
alone (its z), so a single long tube in a user's CAD is aimed at the surface ahead of each point.

Measured across 12 seeds on the case-2 scene (docs/performance.md, "Do the error bars hold?"; CHANGELOG.md, "Aimed scatter"): 16 times less
variance at 15°, 1.75 times at 20°, none at 2°, at the same cost a pass.

Not aimed: faces of lens parts (the photon is in or on the glass), points behind the last surface
(the housing: the connections count what it sends to the detector), glossy cores and mirrors (the
photons follow those themselves), and scenes with a mirror (a folded path has no "ahead" along z).
Only the bidirectional estimator aims; the forward estimator stays the plain walk it is checked by.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.integrators.exit_sampler import ExitDisc
from lensmount.physics.sampler import Streams

AIMED_SHARE = 0.5  # c: an aimed photon's share of directions drawn toward the disc (the rest: the BSDF)
# f cos θ / ((1 − c) p_bsdf + c p_disc) ≤ (f cos θ / p_bsdf) / (1 − c): an aimed photon carries at most this many
# times the weight the BSDF's own sampling would give it (`walk.gain_bound`)
MIXTURE_GAIN = 1.0 / (1.0 - AIMED_SHARE)
MARGIN = 0.05  # the disc's radius: clear semi-diameter × (1 + MARGIN) + 0.5 mm (the view map's exit disc)
DIM_CHOICE, DIM_DISC = 3, 4  # a bounce's Streams dimensions (walk: 0, 1 the BSDF, 2 the roulette)

_CACHE: dict[tuple, tuple] = {}


@dataclass(frozen=True)
class ApertureTargets:
    """discs: one per optical surface, by the z of its plane (ascending); faces (n_tags,): the faces
    whose photons may be aimed (mechanical; `only` narrows them to the broad ones)."""

    discs: tuple[ExitDisc, ...]
    faces: np.ndarray

    @property
    def planes(self) -> np.ndarray:
        return np.array([d.z for d in self.discs])

    def only(self, faces: np.ndarray) -> "ApertureTargets | None":
        """These targets on `faces` (n_tags,) bool as well; None where that leaves no face."""
        keep = self.faces & np.asarray(faces[:len(self.faces)], bool)
        return ApertureTargets(self.discs, keep) if keep.any() else None

    def disc_of(self, position: np.ndarray) -> np.ndarray:
        """(M,) index of the first disc beyond each point along +z; len(discs) behind the last."""
        return np.searchsorted(self.planes, position[:, 2], side="right")

    def aimed(self, tag: np.ndarray, position: np.ndarray) -> np.ndarray:
        """(M,) the photons at (tag, position) that are aimed: an aimable face, a point in front of a disc."""
        return self.faces[tag] & (self.disc_of(position) < len(self.discs))


def aperture_targets(scene) -> ApertureTargets | None:
    """The scene's discs and aimable faces (module docstring), once per geometry in each process (a `pst`
    sweep's scenes differ in their source alone); None without a target (no optics, a mirror, the
    detector not behind the optics along +z, a surface of unknown size)."""
    key = (id(scene.mesh), id(scene.optical), id(scene.detector), id(scene.solid_index_of_tag))
    if key not in _CACHE:
        _CACHE.clear()  # the entry holds what it keys: ids stay unique
        _CACHE[key] = ((scene.mesh, scene.optical, scene.detector, scene.solid_index_of_tag), _targets(scene))
    return _CACHE[key][1]


def _targets(scene) -> ApertureTargets | None:
    optical = list(scene.optical)
    if not optical or any(s.mirror for s in optical) or scene.detector.z <= max(s.z_vertex for s in optical):
        return None
    discs = []
    for s in optical:
        h = float(s.clear_semi_diameter)
        if not math.isfinite(h) or h <= 0:
            h = float(s.mechanical_semi_diameter)
        if not math.isfinite(h) or h <= 0:
            return None
        sag = float(s.profile.sag(np.array([h * h]))[0])
        near = s.z_vertex + min(0.0, sag if math.isfinite(sag) else 0.0)  # the plane in front of the whole surface
        discs.append(ExitDisc(z=float(near), radius=h * (1.0 + MARGIN) + 0.5, facing=1.0))
    mechanical = np.all(np.asarray(scene.solid_index_of_tag) == 1.0, axis=1)
    if not mechanical.any():
        return None
    return ApertureTargets(tuple(sorted(discs, key=lambda d: d.z)), mechanical)


def drawn_toward(streams: Streams, rows) -> np.ndarray:
    """(M,) which of the aimed photons `rows` take their direction from the disc (the rest: from the BSDF)."""
    return streams.at(rows, DIM_CHOICE) < AIMED_SHARE


def disc_directions(targets: ApertureTargets, position, streams: Streams, rows) -> np.ndarray:
    """(M, 3) unit directions from `position` toward uniform points of each point's disc."""
    disc = targets.disc_of(position)
    u = np.column_stack([streams.at(rows, DIM_DISC), streams.at(rows, DIM_DISC + 1)])
    wo = np.zeros((len(disc), 3))
    for k in np.unique(disc):
        sel = np.flatnonzero(disc == k)
        to_q = targets.discs[int(k)].sample_points(position[sel], u[sel]) - position[sel]
        wo[sel] = to_q / np.maximum(np.linalg.norm(to_q, axis=1), 1e-300)[:, None]
    return wo


def mixture_weight(scene, targets: ApertureTargets, tag, position, wi, n, wo) -> np.ndarray:
    """(M,) f cos θ / ((1 − c) p_bsdf + c p_disc) of aimed photons at (tag, position), arriving from wi (toward
    the light) on normals n and leaving along wo, however wo was drawn (module docstring); NaN where the
    finish's value or density is not finite (the walk names it, never a silent 0)."""
    cos_o = np.einsum("ij,ij->i", wo, n)
    f_cos, p_bsdf = np.zeros(len(tag)), np.zeros(len(tag))
    for t in np.unique(tag):
        sel = np.flatnonzero(tag == t)
        bsdf = scene.bsdf_of_tag[int(t)]
        f_cos[sel] = np.asarray(bsdf.eval(wi[sel], wo[sel], n[sel]), np.float64) * np.maximum(cos_o[sel], 0.0)
        p_bsdf[sel] = np.asarray(bsdf.pdf(wi[sel], wo[sel], n[sel]), np.float64)
    p = (1.0 - AIMED_SHARE) * p_bsdf + AIMED_SHARE * disc_pdf(targets, targets.disc_of(position), position, wo)
    good = (p > 0) & (cos_o > 0) & (f_cos > 0)  # below the face, or where the BSDF has nothing: no light
    weight = np.where(good, f_cos / np.where(good, p, 1.0), 0.0)
    weight[~(np.isfinite(f_cos) & np.isfinite(p))] = np.nan
    return weight


def disc_pdf(targets: ApertureTargets, disc: np.ndarray, position: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Solid-angle density (M,) of directions wo from `position` drawn toward disc `disc` (0 where ω misses it)."""
    pdf = np.zeros(len(disc))
    for k in np.unique(disc[disc < len(targets.discs)]):
        sel = np.flatnonzero(disc == k)
        d = targets.discs[int(k)]
        wz = wo[sel, 2]
        ahead = wz > 1e-12
        t = np.where(ahead, (d.z - position[sel, 2]) / np.where(ahead, wz, 1.0), -1.0)
        q = position[sel] + np.maximum(t, 0.0)[:, None] * wo[sel]
        inside = ahead & (t > 0)
        area = np.where(inside, d.area_pdf(position[sel], q), 0.0)
        pdf[sel] = np.where(inside, area * t * t / np.where(ahead, wz, 1.0), 0.0)  # |q − x| = t for a unit ω
    return pdf


__all__ = ["MIXTURE_GAIN", "ApertureTargets", "aperture_targets", "disc_directions", "disc_pdf", "drawn_toward", "mixture_weight"]
