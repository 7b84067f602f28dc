"""What one pass of any integrator produces, and the film and ledger it is built from.

Passes are independent by construction (see the estimator reference), so the
run's answer is the mean of the passes and its error bar is their spread.

- `Film`: the detector image of one pass, one channel per part (the last scattering
  vertex's part) plus `direct` and `ghosts` when the scene turns those effects on. Both
  integrators deposit into it: photons by where they land, the gather as an image.
- `EnergyLedger`: where the emitted flux went (docs/bidirectional.md, "energy ledger"):
  source = detector + absorbed + escaped + glass + lost. Every entry is a flux in units of
  E_sun·mm², the same as `PassEstimate.flux`.
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from dataclasses import dataclass, field, replace

import numpy as np

from lensmount.integrators.paths import EMPTY, FaceTally, PassFaces, PassPaths, PathTally, binning, ghost_code
from lensmount.scene.scene import optical_faces, scattering_tags

DIRECT, GHOSTS = "direct", "ghosts"
BY_ROUTES = -2  # `Film.channel` of a photon whose path the deterministic ghost routes count instead


@dataclass
class PassEstimate:
    """One pass's estimate of detector irradiance, normalised by the source irradiance E_sun.

    image : (ny, nx) float64, E/E_sun per pixel (dimensionless); row 0 is the detector's -y edge
    per_part : (P, ny, nx) float64, the same split by channel (`Film.channels`)
    part_names : P channel names, aligned with `per_part`
    pixel_area_mm2 : area of one pixel
    photons : photons traced in this pass
    ledger : the pass's energy ledger (`EnergyLedger.as_dict`), mm² (flux / E_sun)
    diagnostics : counts that are not flux, e.g. `view_map_samples`, `view_map_lost_samples`
        (backward rays ended by the tracer's numerical guards), and `time/<phase>` seconds
        (`phase_times`; the plan's times, kept out of summary.json's diagnostics)
    radius_scale : s_i, the pass's gather radius relative to r_0 (0: no density estimate, no kernel bias)
    part_flux_ladder : (L, P) per-part flux (mm²) of the same pass with every gather radius r taken as
        r · BIAS_LADDER[l] (`photon_gather`; same photons and hit points; None when the pass has no
        density estimate). How it changes with the radius measures the kernel bias (`analysis.bias`).
    paths : the same light by path signature (`integrators.paths`: ordered scatter faces, ghosts)
    faces : light per CAD face: flux arriving (illuminated), étendue seen by the detector (critical)
    largest : (LARGEST,) the largest single contributions (mm²) to the pass's flux, descending, zero-padded
        (`Largest`: photons landing or connected, photon × hit-point pairs gathered; None when not kept).
        Their fall-off is the tail of what a pass sums (`analysis.passes.tail_index`).
    term_bound : the largest any single contribution of this pass could be (mm²), whether or not one was drawn:
        a forward photon's flux is bounded by its emitted flux times its finishes' weights (`walk.gain_bound`);
        inf where the estimator states none (a gathered or connected term grows without bound as its kernel
        or its distance shrinks). A bounded pass is a sum of bounded independent terms: its spread is an error
        bar by the central limit, not a power-law tail (`analysis.passes.Accumulator.tail`).
    """

    image: np.ndarray
    per_part: np.ndarray
    part_names: list[str]
    pixel_area_mm2: float
    photons: int
    ledger: dict[str, float] = field(default_factory=dict)
    diagnostics: dict[str, float] = field(default_factory=dict)
    radius_scale: float = 0.0
    part_flux_ladder: np.ndarray | None = None
    paths: PassPaths | None = None
    faces: PassFaces | None = None
    largest: np.ndarray | None = None
    term_bound: float = math.inf

    @property
    def flux(self) -> float:
        """Detector stray flux normalised by E_sun (mm²)."""
        return float(self.image.sum() * self.pixel_area_mm2)

    @property
    def part_flux(self) -> np.ndarray:
        """(P,) flux per part, normalised by E_sun (mm²)."""
        return self.per_part.sum(axis=(1, 2)) * self.pixel_area_mm2

    def totals(self) -> "PassEstimate":
        """This pass summed over the detector: `image` and `per_part` one pixel each, holding the sum of
        their pixels (the same `pixel_area_mm2`), the paths and faces their totals without images.

        `flux`, `part_flux`, the ladder, the ledger and the diagnostics are exactly this pass's (the sum
        of one value is that value), so an Accumulator of totals (shape (1, 1)) reads the same flux,
        error bar, bias bound and stopping decision as one of the whole passes. What a sweep keeps
        of a pass (`loop.pst`): case 2's 19 channels of 600 × 600 pixels are 55 MB a pass and angle."""
        paths = None if self.paths is None else replace(
            self.paths, image_signature=np.zeros(0, np.int64), image_pixel=np.zeros(0, np.int64),
            image_value=np.zeros(0), shape=(1, 1), block=1)
        faces = None if self.faces is None else replace(
            self.faces, seen_tag=np.zeros(0, np.int64), seen_pixel=np.zeros(0, np.int64), seen_value=np.zeros(0))
        return replace(self, image=np.full((1, 1), self.image.sum()),
                       per_part=self.per_part.sum(axis=(1, 2))[:, None, None], paths=paths, faces=faces)

    @property
    def lost_flux(self) -> float:
        """Flux the walk could not follow to its end (the ledger's `lost/…` entries), mm²."""
        return float(sum(v for k, v in self.ledger.items() if k.startswith("lost/")))


TIME_PREFIX = "time/"  # diagnostics keys holding seconds per phase, summed over passes (the plan's times)
AIMED_PASSES = "passes/photons aimed at the diaphragm edge"  # diagnostics key, summed over passes
UNAIMED_PASSES = "passes/diaphragm edge too rarely lit to aim at"  # diagnostics key, summed over passes
# Aimed photons' first arrivals at the diaphragm edge by emission component (`photon_target.COMPONENTS`):
# Σ Φ and Σ Φ² (mm², mm⁴), summed over passes; `plan.Plan.as_dict` turns them into shares and spreads.
EDGE_FLUX = "edge flux/"
EDGE_FLUX_SQ = "edge flux squared/"
# The pilot's check of its ring (`photon_target.PilotCheck`), summed over aimed passes: the share of the edge's
# light its check photons found outside the fitted ring(s), the rings added for it, the share outside after.
PILOT_MISSED, PILOT_RINGS_ADDED, PILOT_MISSED_AFTER = (
    "pilot check/edge light outside the ring", "pilot check/rings added", "pilot check/edge light outside after")
PHASES = {"view_map": "scatter: view map (hit points)", "gather": "scatter: gather at hit points",
          "walk": "photon walk (scatter, direct and ghosts together)",
          "ghost_routes": "ghosts: deterministic two- (four-) reflection routes"}


LARGEST = 16  # a pass's largest contributions kept (`Largest`): 8 passes give the tail index its 64 and more


class Largest:
    """The LARGEST largest values of everything added (a pass's single contributions to its flux).

    Why a pass keeps them: a pass is a sum over many photons (and photon × hit-point pairs), and how its
    largest terms fall off, x_(i) ∝ i^(−1/α), shows a heavy tail (α ≤ 3) in every pass, long before one
    pass is large enough to stand out among the others (`analysis.passes.tail_index`)."""

    def __init__(self):
        self.values = np.zeros(LARGEST)  # descending

    def add(self, values: np.ndarray) -> None:
        values = np.asarray(values, np.float64).ravel()
        if len(values) > LARGEST:
            values = np.partition(values, -LARGEST)[-LARGEST:]
        self.values = -np.sort(-np.concatenate([self.values, values]))[:LARGEST]


CPU_SUFFIX = ", CPU"  # after a phase's name: its CPU seconds, beside the wall seconds under the bare name


def phase_clock() -> np.ndarray:
    """(wall, CPU) seconds now; a phase's cost is the difference of two readings (`phase_times`)."""
    return np.array([time.perf_counter(), time.process_time()])


def phase_times(**seconds) -> dict[str, float]:
    """Diagnostics entries for the seconds a pass spent per phase (`PHASES`: which effect it serves): a
    phase's wall seconds, or its (wall, CPU) pair (differences of `phase_clock`), the CPU under the
    name + CPU_SUFFIX. Why both: on a shared machine the wall time says how loaded it was as much as what
    the phase costs; the CPU time (this process, every thread) is the cost."""
    out = {}
    for k, v in seconds.items():
        wall, *cpu = np.atleast_1d(np.asarray(v, np.float64))
        out[TIME_PREFIX + PHASES[k]] = float(wall)
        if cpu:
            out[TIME_PREFIX + PHASES[k] + CPU_SUFFIX] = float(cpu[0])
    return out


def scattering_parts(scene) -> np.ndarray:
    """(n_parts,) bool: parts with at least one face that scatters (`scattering_tags`)."""
    mesh = scene.mesh
    on = np.zeros(len(mesh.parts), bool)
    if mesh.tag_table:
        on[mesh.part_of_tag()[scattering_tags(scene)]] = True
    return on


def film_channels(scene) -> list[str]:
    """The channels every integrator reports for `scene`: the parts that scatter (in mesh order),
    then `direct` (direct on) and `ghosts` (ghosts on).

    A part whose every face absorbs is never a path's last scattering vertex, so its image is
    zero by construction: it gets no channel. Why: a film holds one (ny, nx) image per channel
    in every worker and in the accumulator; case 1 at 2400 × 2400 px with all 20 parts held
    0.9 GB per copy, with the one scattering part 46 MB."""
    parts = [p for p, on in zip(scene.mesh.parts, scattering_parts(scene)) if on]
    return parts + ([DIRECT] if scene.effects.direct else []) + ([GHOSTS] if scene.effects.ghosts else [])


def face_tally(scene) -> FaceTally:
    """An empty per-face tally for `scene`'s detector, binned as the film's path images (`paths.binning`)."""
    det = scene.detector
    return FaceTally(len(scene.mesh.tag_table), det.shape, det.pixel_area, binning(det.shape),
                     left_out=optical_faces(scene.mesh.tag_table))


class Film:
    """The detector image of one pass, by channel (see the module docstring).

    by_routes : Fresnel reflection counts whose unscattered light the deterministic ghost routes
        count (`ghost_routes.route_reflections`); photons on such paths get channel BY_ROUTES.
    seen : the faces the pass's view map saw (`face_tally`, filled by `view_map.build_view_map`); the
        film's per-face tally starts from a copy of it (None: from nothing, a pass without a view map)."""

    def __init__(self, scene, by_routes: tuple[int, ...] = (), seen: FaceTally | None = None):
        self.detector = scene.detector
        self.channels = film_channels(scene)
        mesh = scene.mesh
        lit = scattering_parts(scene)
        # channel of each part (-1: it never scatters), and of each tag through its part
        self._of_part = np.where(lit, np.cumsum(lit) - 1, -1).astype(np.int64)
        self.channel_of_tag = self._of_part[mesh.part_of_tag()] if mesh.tag_table else np.zeros(0, np.int64)
        self._direct = self.channels.index(DIRECT) if DIRECT in self.channels else -1
        self._ghosts = self.channels.index(GHOSTS) if GHOSTS in self.channels else -1
        self.by_routes = tuple(by_routes)
        det = self.detector
        self._n_pix = det.nx * det.ny
        self._flux = np.zeros(len(self.channels) * self._n_pix)  # Σ Φ·response per (channel, pixel)
        self._images = np.zeros((len(self.channels), det.ny, det.nx))  # gathered E/E_sun
        response = det.spectral_weight
        self._response = None if response is None else np.asarray(response, np.float64)
        self.paths = PathTally(det.shape, det.pixel_area)
        self.faces = face_tally(scene) if seen is None else seen.copy()
        self.largest = Largest()  # the largest single contributions (mm²): deposits here, the gather's added

    def channel(self, part: np.ndarray, reflections: np.ndarray) -> np.ndarray:
        """(N,) channel of paths whose last scattering part is `part` (-1: none) after `reflections`
        Fresnel reflections; -1 where the path belongs to an effect the scene turned off."""
        unscattered = part < 0
        ch = np.where(unscattered, self._direct, self._of_part[np.maximum(part, 0)] if len(self._of_part) else -1)
        if self._ghosts >= 0:
            ch = np.where(unscattered & (reflections > 0), self._ghosts, ch)
            ch = np.where(unscattered & np.isin(reflections, self.by_routes), BY_ROUTES, ch)
        return ch.astype(np.int64)

    def deposit(self, pixel: np.ndarray, flux: np.ndarray, wavelength: np.ndarray, channel: np.ndarray,
                signature: np.ndarray) -> None:
        """Photons of flux (N,) [E_sun·mm²] landing in flat pixels (N,) (>= 0), into channels (N,) (>= 0),
        by paths `signature` (N,) (`integrators.paths`)."""
        if not len(pixel):
            return
        value = flux if self._response is None else flux * self._response[np.asarray(wavelength, np.int64)]
        self._flux += np.bincount(channel * self._n_pix + pixel, weights=value, minlength=len(self._flux))
        self.paths.add(signature, pixel, value / self.detector.pixel_area)
        self.largest.add(value)

    def deposit_route(self, route: tuple[int, ...], pixel: np.ndarray, flux: np.ndarray,
                      wavelength: np.ndarray) -> None:
        """Rays of one deterministic ghost route (`trace.ghosts`, 1-based reflecting surfaces) landing in
        flat pixels (N,) (>= 0): into the `ghosts` channel, under the route's path signature."""
        n = len(pixel)  # the photons' ghost code: reflection count and the first two surfaces (0-based)
        code = ghost_code(np.full(n, len(route)), np.full(n, route[0] - 1), np.full(n, route[1] - 1))
        signature = self.paths.extend(np.full(n, EMPTY), code)
        self.deposit(pixel, flux, wavelength, np.full(len(pixel), self._ghosts), signature)

    def add_images(self, per_channel: np.ndarray) -> None:
        """Irradiance images (channels, ny, nx) E/E_sun estimated otherwise (the gather)."""
        self._images += per_channel

    def estimate(self, photons: int, ledger: "EnergyLedger", diagnostics: dict | None = None,
                 term_bound: float = math.inf) -> PassEstimate:
        """The pass's estimate; term_bound: what bounds a single contribution (`PassEstimate.term_bound`)."""
        det = self.detector
        per_part = self._images + self._flux.reshape(self._images.shape) / det.pixel_area
        bad = ~np.isfinite(per_part)
        if bad.any():  # never zeroed: a NaN here is a bug upstream and zeroing it would hide light
            c, iy, ix = np.argwhere(bad)[0]
            raise FloatingPointError(f"non-finite irradiance in channel '{self.channels[c]}' at pixel (x={ix}, "
                                     f"y={iy}) ({int(bad.sum())} values in all)")
        return PassEstimate(image=per_part.sum(axis=0), per_part=per_part, part_names=list(self.channels),
                            pixel_area_mm2=det.pixel_area, photons=int(photons), ledger=ledger.as_dict(),
                            diagnostics=dict(diagnostics or {}), paths=self.paths.finish(), faces=self.faces.finish(),
                            largest=self.largest.values.copy(), term_bound=float(term_bound))


class EnergyLedger:
    """Where the flux of one pass went: named sums, E_sun·mm² (see docs/bidirectional.md).

    Entries: `source`; `detector/<channel>` (photons the film counts), `detector_gathered/<channel>`
    (bidirectional: photons whose last vertex is gathered, so the image counts them through the
    gather instead), `detector_effect_off` (direct or ghost light the scene turned off),
    `detector_ghost_routes` (photons on ghost paths the deterministic routes count instead);
    `absorbed/<part>` (arriving minus scattered flux, per sample); `escaped` (left the assembly, or
    hit the detector's back); `glass` (what the optics took: Fresnel reflection discarded when
    ghosts are off, and bulk absorption along paths in glass); `lost/bounce_limit`, `lost/tracer_guard`; `roulette_balance` (flux of the
    photons Russian roulette killed minus what the survivors gained: zero in expectation).
    """

    def __init__(self):
        self._sums: dict[str, float] = defaultdict(float)

    def add(self, name: str, flux) -> None:
        self._sums[name] += float(np.sum(flux))

    def add_by(self, prefix: str, names: list[str], index: np.ndarray, flux: np.ndarray) -> None:
        """Σ flux per `names[index]` into `prefix/<name>` (index (N,) >= 0)."""
        if not len(index):
            return
        sums = np.bincount(index, weights=flux, minlength=len(names))
        for i in np.flatnonzero(np.bincount(index, minlength=len(names))):
            self._sums[f"{prefix}/{names[i]}"] += float(sums[i])

    def as_dict(self) -> dict[str, float]:
        return dict(sorted(self._sums.items()))


def ledger_residual(ledger: dict[str, float]) -> float:
    """source − Σ(every other entry), relative to the source (0 for a balanced ledger or no source)."""
    source = ledger.get("source", 0.0)
    rest = sum(v for k, v in ledger.items() if k != "source")
    return (source - rest) / source if source else 0.0


__all__ = ["PassEstimate", "Film", "Largest", "LARGEST", "EnergyLedger", "face_tally", "film_channels", "scattering_tags", "scattering_parts",
           "ledger_residual", "phase_clock", "phase_times", "DIRECT", "GHOSTS", "BY_ROUTES", "TIME_PREFIX",
           "CPU_SUFFIX", "PHASES"]
