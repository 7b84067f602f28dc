"""The face-aware density estimate: photons deposit flux into view-map hit points.

At hit point y (outgoing direction ω_o toward the detector, radius r) the radiance is

    L_o(y, ω_o) ≈ Σ_p f(y, ω_p → ω_o) Φ_p / A(y),   A = π r² minus what lies off the face

over the photons p that landed within r of y *on the same CAD face* (same tag) and
on the same side (normals within `max_normal_deg`). Without the face test a disc of
r > 25 µm around a point on the 50 µm diaphragm edge would also collect the photons
on the plate's faces, whose irradiance is orders of magnitude higher.

ω_p is the photon's incidence on its own facet, turned with the face from its normal to the hit
point's (`turned`): a photon's flux landed on the face, so it counts at every hit point of its disc,
with the angle of incidence it had. Tested in its world direction instead, a grazing photon on a
curved face lies behind the tangent plane of hit points a few degrees around the bend and was
dropped there: on case 1's bore (R = 16.3 mm, light at 1–3° grazing near the ends of the lit arc)
0.2–1 % of a pass's flux at r, more at each wider radius of the bias ladder. That loss is a kernel
bias of no power of the radius: the ladder read it as a curve flattening outward and 19 % of
default case-1 runs could not bound their bias.

Neighbour search: hit points are grouped by (tag, radius octave) and each group gets
one cKDTree per view map (`search_groups`); photons of a tag get one tree per bounce; the pairs come back
as flat arrays from `sparse_distance_matrix(..., output_type="ndarray")` — no Python
loop over photons or hit points, only over (tag, octave) groups.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from lensmount.integrators.estimate import Largest
from lensmount.integrators.lobe_core import outside_core
from lensmount.integrators.settings import EstimatorSettings

# The radii, relative to a pass's r, at which the gather also estimates each hit point's radiance from
# the same photons (`Gatherer.radiance_ladder`): the curve Ê(ρ) near ρ = r that the bias estimate reads
# (`analysis.bias`). Wider than r, where the discs hold more photons and hit points, so that the curve's
# steps are far less noisy than a step to r/2 (whose quarter of the photons made the old bound as noisy as
# the estimate itself; r/2 stays on the ladder so a run can still be compared with that bound).
# Index 0 is r itself.
BIAS_LADDER = (1.0, math.sqrt(2.0), 2.0, math.sqrt(0.5), 0.5)


@dataclass
class HitPoints:
    """The view map of one pass (stage 1's output). H hit points.

    position : (H, 3) mm
    normal : (H, 3) unit, on the side the backward ray came from (the side of ω_o)
    omega_o : (H, 3) unit, from the surface toward the detector (the BSDF's wo)
    weight : (H,) τ: backward weight / samples per pixel, so pixel E = Σ τ L_o
    pixel : (H,) int64 flat pixel index (row-major, (ny, nx))
    tag : (H,) int32 CAD face tag
    wavelength : (H,) int32 wavelength index
    radius : (H,) mm, gather radius of this pass (r_0 · s_i)
    area : (H,) mm², the part of the gather disc on the hit point's face (π r² away from boundaries)
    area_ladder : (H, L) mm², the same for the discs of radius r · BIAS_LADDER[l] (the bias estimate,
        `Gatherer.radiance_ladder`)
    """

    position: np.ndarray
    normal: np.ndarray
    omega_o: np.ndarray
    weight: np.ndarray
    pixel: np.ndarray
    tag: np.ndarray
    wavelength: np.ndarray
    radius: np.ndarray
    area: np.ndarray | None = None
    area_ladder: np.ndarray | None = None

    def __post_init__(self):
        r = np.asarray(self.radius, np.float64)
        if self.area is None:
            self.area = np.pi * r ** 2
        if self.area_ladder is None:
            self.area_ladder = np.pi * (r[:, None] * np.asarray(BIAS_LADDER)) ** 2

    def __len__(self) -> int:
        return len(self.weight)

    @classmethod
    def empty(cls) -> "HitPoints":
        z3, z = np.zeros((0, 3)), np.zeros(0)
        return cls(z3, z3.copy(), z3.copy(), z, np.zeros(0, np.int64), np.zeros(0, np.int32),
                   np.zeros(0, np.int32), z.copy(), z.copy(), np.zeros((0, len(BIAS_LADDER))))

    def subset(self, index) -> "HitPoints":
        return HitPoints(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @staticmethod
    def concatenate(parts: list["HitPoints"]) -> "HitPoints":
        if not parts:
            return HitPoints.empty()
        return HitPoints(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(HitPoints)})


@dataclass
class PhotonHits:
    """Photons arriving at scattering surfaces in one bounce. M photons.

    position : (M, 3); direction : (M, 3) travel direction (toward the surface);
    normal : (M, 3) unit, on the side the photon came from; flux : (M,) Φ in E_sun·mm²;
    tag : (M,) int32; wavelength : (M,) int32
    signature : (M,) int64 path signature ending with the scatter at this face (`integrators.paths`);
        the empty path when the caller does not follow paths
    """

    position: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    flux: np.ndarray
    tag: np.ndarray
    wavelength: np.ndarray
    signature: np.ndarray | None = None

    def __post_init__(self):
        if self.signature is None:
            self.signature = np.zeros(len(self.flux), np.int64)


def turned(v: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 3) each v turned by the rotation that takes unit normal a to unit normal b about a × b (Rodrigues:
    v·c + k × v + k (k·v) / (1 + c), k = a × b, c = a·b); the angle of v to a is its angle to b. Normals
    within the gather's band (c ≥ cos 89°) keep 1 + c away from 0."""
    k = np.cross(a, b)
    c = np.einsum("ij,ij->i", a, b)
    return (v * c[:, None] + np.cross(k, v)
            + k * (np.einsum("ij,ij->i", k, v) / np.maximum(1.0 + c, 1e-12))[:, None])


INCIDENCES_DEG = (0.0, 20.0, 40.0, 60.0, 75.0)  # incidences on mount faces (the sun through a lens: any)


def gatherable_share(bsdf, core: float, n_u: int = 48) -> float:
    """Share of the BSDF's albedo outside the core |Δβ| < core around the mirror direction,
    averaged over `INCIDENCES_DEG`: the part of the lobe a gather at hit points can catch.

    Deterministic: the BSDF's own sampling on a stratified n_u × n_u grid (weights f cos/pdf)."""
    g = (np.arange(n_u) + 0.5) / n_u
    u = np.column_stack([np.repeat(g, n_u), np.tile(g, n_u)])
    n = np.tile([0.0, 0.0, 1.0], (len(u), 1))
    shares = []
    for theta in np.radians(INCIDENCES_DEG):
        wi = np.tile([math.sin(theta), 0.0, math.cos(theta)], (len(u), 1))
        wo, w, _ = bsdf.sample(wi, n, u)
        w = np.where(np.isfinite(w) & (w > 0), w, 0.0)
        total = float(w.sum())
        shares.append(float(w[outside_core(wi, wo, n, core)].sum()) / total if total > 0 else 0.0)
    return float(np.mean(shares))


REACH = max(BIAS_LADDER)  # the widest disc the pair search must find, relative to a hit point's r


def search_groups(hits: HitPoints) -> dict[int, list[tuple[np.ndarray, cKDTree, float]]]:
    """The hit points by face and radius octave, one KD-tree a group: {tag: [(indices, tree, reach)]}, reach
    the farthest a pair of the group can lie (REACH × its largest radius). They read the hit points alone, so
    they belong to the view map (`bidirectional.ViewMap.groups`: built once a pass, every source's photons
    gathered at them; `pst` gathered each angle's at trees of its own, ~7 % of an angle's pass)."""
    groups: dict[int, list[tuple[np.ndarray, cKDTree, float]]] = {}
    index = np.arange(len(hits))
    if len(index) == 0:
        return groups
    octave = np.floor(np.log2(np.maximum(hits.radius[index], 1e-12))).astype(np.int64)
    key = hits.tag[index].astype(np.int64) * 4096 + (octave + 2048)
    by_key = np.argsort(key, kind="stable")
    order = index[by_key]
    uniq, starts = np.unique(key[by_key], return_index=True)
    ends = np.append(starts[1:], len(order))
    for k, s, e in zip(uniq, starts, ends):
        idx = order[s:e]
        groups.setdefault(int(k // 4096), []).append((idx, cKDTree(hits.position[idx]),
                                                      REACH * float(hits.radius[idx].max())))
    return groups


class Gatherer:
    """Hit points indexed for the pass; `gather(photons)` adds Σ f Φ / A into `radiance`.

    bsdf_of_tag : list indexed by tag of objects with `eval(wi, wo, n) -> (N,)` (None = no gather)
    max_normal_deg : photons whose surface normal differs more than this from the hit
        point's (other side of a sheet, another facet under a shared tag) are not gathered
    detector_z : photons at z ≥ detector_z landed where the detector cannot see (it faces −z);
        they are not gathered (the on-face area ends at that plane too, `FaceBoundaries`)
    core_of_tag : (n_tags,) half width (direction cosines) of the lobe core that the photons
        count themselves on a glossy finish (`bidirectional.gather_cores`); f is gathered only
        outside it (`outside_core`). None or 0: the whole lobe is gathered.

    paths : a `paths.PathTally` that gets every photon–hit-point contribution to the detector
        irradiance (τ f Φ / A into the hit point's pixel) under the photon's signature; None: not kept.

    groups : the hit points' `search_groups` (None: made here); a view map's, shared by every source's photons

    `largest` (`estimate.Largest`) keeps the largest single photon–hit-point contributions τ f Φ / A (units of
    the image: times the pixel area, a flux): the tail of what the pass sums (`analysis.passes.tail_index`).

    `radiance_ladder` (H, L) is the same estimate over the discs of radius r · BIAS_LADDER[l] (same
    photons, areas `area_ladder`): how it changes with the radius measures the kernel bias of the pass
    (`analysis.bias`).
    """

    def __init__(self, hits: HitPoints, bsdf_of_tag, max_normal_deg: float = EstimatorSettings.normal_limit_deg, chunk: int = 100_000,
                 detector_z: float | None = None, core_of_tag: np.ndarray | None = None, paths=None,
                 groups: dict | None = None):
        self.hits = hits
        self.paths = paths
        self.chunk = int(chunk)
        self.bsdf_of_tag = bsdf_of_tag
        self.core_of_tag = core_of_tag
        self.cos_max = math.cos(math.radians(max_normal_deg))
        # The ladder's wider discs take a normal band as much wider: r_0 is capped at the chord of the
        # face's tightest bend that keeps max_normal_deg (`radius.radius_caps`), so a disc m times
        # wider spans m times the turn; with the plain band it lost the photons beyond it on a curved
        # edge (0.80 of the truth at √2 r on a 2 mm cylinder) and read a bias that is not the run's.
        self._cos_ladder = np.cos(np.radians(np.minimum(max_normal_deg * np.maximum(BIAS_LADDER, 1.0), 89.0)))
        self.detector_z = math.inf if detector_z is None else float(detector_z)
        self.radiance = np.zeros(len(hits))  # Σ f Φ / A per hit point, units E_sun/sr
        self.radiance_ladder = np.zeros((len(hits), len(BIAS_LADDER)))
        self._rungs = np.asarray(BIAS_LADDER, np.float64)
        self._ladder_sums = np.zeros_like(self.radiance_ladder)  # `_add_ladder`'s per-chunk sums, kept zero
        self._touched = np.zeros(len(hits), np.bool_)
        self._reach = REACH
        self.pairs_tested = 0
        self.groups = search_groups(hits) if groups is None else groups
        self.largest = Largest()

    def gather(self, photons: PhotonHits) -> None:
        """Deposit one bounce of photons into the hit points within their radius on the same face."""
        if len(self.hits) == 0 or len(photons.flux) == 0:
            return
        for tag in np.intersect1d(np.unique(photons.tag), np.fromiter(self.groups, dtype=np.int64)):
            bsdf = self.bsdf_of_tag[int(tag)] if int(tag) < len(self.bsdf_of_tag) else None
            if bsdf is None:
                continue
            on_face = np.flatnonzero((photons.tag == tag) & (photons.position[:, 2] < self.detector_z))
            for start in range(0, len(on_face), self.chunk):
                self._gather_face(int(tag), bsdf, on_face[start:start + self.chunk], photons)

    def _gather_face(self, tag: int, bsdf, pidx: np.ndarray, photons: PhotonHits) -> None:
        """Photons pidx (one face, one chunk: chunks bound the memory of the pair arrays)."""
        h = self.hits
        ptree = cKDTree(photons.position[pidx])
        for hidx, htree, rmax in self.groups[tag]:
            pairs = htree.sparse_distance_matrix(ptree, rmax, output_type="ndarray")
            if len(pairs) == 0:
                continue
            self.pairs_tested += len(pairs)
            # The scalar tests first, compiled, on every pair (~3 in 4 fail: another wavelength, beyond the
            # hit point's own widest disc); the normals are gathered only for the pairs left, in order.
            near = _pairs_in_reach(pairs["i"], pairs["j"], pairs["v"], hidx, pidx, h.radius, self._reach,
                                   h.wavelength, photons.wavelength)
            if not len(near):
                continue
            hi, pj, v = hidx[pairs["i"][near]], pidx[pairs["j"][near]], pairs["v"][near]
            n_h, n_p = h.normal[hi], photons.normal[pj]
            cos_n = np.einsum("ij,ij->i", n_h, n_p)
            # The photon's incidence as it met its own facet, turned onto the hit point's (`turned`): a test of
            # its world direction against the hit point's tangent plane dropped the grazing photons of a curved
            # face more the wider the disc, a loss no power of the radius describes (module docstring).
            wi = turned(-photons.direction[pj], n_p, n_h)
            keep = (cos_n > self._cos_ladder.min()) & (np.einsum("ij,ij->i", n_h, wi) > 0.0)
            if not keep.any():
                continue
            hi, pj, wi, n_h, v, cos_n = hi[keep], pj[keep], wi[keep], n_h[keep], v[keep], cos_n[keep]
            f = np.asarray(bsdf.eval(wi, h.omega_o[hi], n_h), dtype=np.float64)
            core = 0.0 if self.core_of_tag is None else float(self.core_of_tag[tag])
            if core > 0:  # the lobe's core is the photons' to count (glossy rule): gather the rest only
                f = np.where(outside_core(wi, h.omega_o[hi], n_h, core), f, 0.0)
            contrib = np.maximum(f, 0.0) * photons.flux[pj]
            distance = v / h.radius[hi]
            if not _add_ladder(hi, contrib, distance, cos_n, self._rungs, self._cos_ladder, h.area_ladder,
                               self.radiance_ladder, self._ladder_sums, self._touched):
                # never zeroed: it hides light
                raise FloatingPointError(f"non-finite gather value on face tag {tag} at "
                                         f"{int(np.sum(~np.isfinite(contrib)))} photon-hit pairs (the finish's "
                                         f"BSDF value or the hit point's area is not finite)")
            inside = (distance < 1.0) & (cos_n > self.cos_max)
            hi_r, value = hi[inside], contrib[inside] / h.area[hi[inside]]
            self.radiance += np.bincount(hi_r, weights=value, minlength=len(h))
            self.largest.add(h.weight[hi_r] * value)
            if self.paths is not None:
                self.paths.add(photons.signature[pj[inside]], h.pixel[hi_r], h.weight[hi_r] * value)

    def part_flux_ladder(self, channel_of_tag: np.ndarray, n_channels: int) -> np.ndarray:
        """(L, C) Σ τ L_o per channel at each radius of BIAS_LADDER, as a sum over pixels (multiply by the
        pixel area)."""
        h = self.hits
        ch = (channel_of_tag[h.tag] if len(h) else np.zeros(0, np.int64)).astype(np.int64)
        return np.array([np.bincount(ch, weights=h.weight * self.radiance_ladder[:, rung], minlength=n_channels)
                         [:n_channels] for rung in range(len(BIAS_LADDER))])

    def image(self, shape: tuple[int, int], channel_of_tag: np.ndarray, n_channels: int):
        """(ny, nx) image and (C, ny, nx) per-channel images of Σ τ L_o per pixel (channel_of_tag:
        `Film.channel_of_tag`; hit points lie on scattering faces only, so every one has a channel)."""
        ny, nx = shape
        h = self.hits
        value = h.weight * self.radiance
        if not np.all(np.isfinite(value)):
            bad = np.flatnonzero(~np.isfinite(value))
            raise FloatingPointError(f"non-finite hit-point value at {len(bad)} hit point(s), e.g. pixel "
                                     f"{int(h.pixel[bad[0]])} on face tag {int(h.tag[bad[0]])}")
        image = np.bincount(h.pixel, weights=value, minlength=ny * nx)[: ny * nx].reshape(ny, nx)
        ch = channel_of_tag[h.tag] if len(h) else np.zeros(0, np.int64)
        flat = ch.astype(np.int64) * (ny * nx) + h.pixel
        per_channel = np.bincount(flat, weights=value, minlength=n_channels * ny * nx)[: n_channels * ny * nx]
        return image, per_channel.reshape(n_channels, ny, nx)


@njit(cache=True)
def _pairs_in_reach(i, j, distance, hidx, pidx, radius, reach, hit_wavelength, photon_wavelength):
    """Positions (ascending) of the pairs (hit point hidx[i], photon pidx[j] at `distance`) within reach × the
    hit point's radius and of its wavelength: the numpy test's comparisons, one pair at a time (no (pairs,)
    temporaries: case 1 tests ~8 × 10⁶ pairs a pass and keeps ~1 in 4)."""
    out = np.empty(len(i), np.int64)
    n = 0
    for k in range(len(i)):
        h = hidx[i[k]]
        p = pidx[j[k]]
        if distance[k] < reach * radius[h] and hit_wavelength[h] == photon_wavelength[p]:
            out[n] = k
            n += 1
    return out[:n]


@njit(cache=True, error_model="numpy")  # a zero area gives inf or nan, reported as not finite (not raised)
def _add_ladder(hit, contrib, distance, cos_n, rungs, cos_rungs, area_ladder, radiance_ladder, sums, touched):
    """One chunk's pairs (hit point `hit`, `contrib` = f Φ, `distance` / r, `cos_n` between the normals) into
    `radiance_ladder` (H, L): at rung l a pair adds contrib · (1 / area_ladder[hit, l]) when within
    rungs[l] and cos_rungs[l], else contrib · (0 / area). False when any of those products is not finite.

    The numbers of the numpy form it replaces, one (pairs,) bincount per rung added into its column: each
    hit point's pairs summed from 0 in pair order (in `sums`, zero between calls, `touched` marking its
    rows), then added to the column once. One pass over the pairs instead of five bincounts of length H."""
    n_l = rungs.size
    rows = np.empty(hit.size, np.int64)
    m = 0
    finite = True
    for p in range(hit.size):
        h = hit[p]
        if not touched[h]:
            touched[h] = True
            rows[m] = h
            m += 1
        for l in range(n_l):
            within = 1.0 if distance[p] < rungs[l] and cos_n[p] > cos_rungs[l] else 0.0
            w = contrib[p] * (within / area_ladder[h, l])
            finite &= math.isfinite(w)
            sums[h, l] += w
    for i in range(m):
        h = rows[i]
        touched[h] = False
        for l in range(n_l):
            radiance_ladder[h, l] += sums[h, l]
            sums[h, l] = 0.0
    return finite


__all__ = ["BIAS_LADDER", "REACH", "HitPoints", "PhotonHits", "Gatherer", "search_groups", "turned", "gatherable_share", "INCIDENCES_DEG"]
