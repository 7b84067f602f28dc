"""Bidirectional stochastic ray tracing (Zhdanov et al. 2016) as independent progressive passes.

One pass = three phases, as pbrt-v4's SPPM reads (`view_pass` is phase 1, `photon_pass` phases 2
and 3, `run_pass` both; the view map does not depend on the source, so a sweep over source
directions gathers every direction's photons of pass i at pass i's view map, `ViewMap`):

1. View map (`view_map.build_view_map`): backward samples from every pixel, through
   the optics, to the first broad scatterer they meet → hit points with weight τ,
   outgoing direction ω_o and radius r = r_0 · s_i.
2. Photons: Φ = A_S/N each (units of E_sun), traced forward through the optics; at
   every scattering face they meet they deposit into the hit points on the same face
   within r (`photon_gather.Gatherer`: Σ f Φ / (π r²)), then continue by sampling the
   BSDF, with Russian roulette on the throughput, so inter-reflections count. On a broad
   mechanical face in front of an optical surface half the directions are drawn toward that
   surface's clear aperture instead, weighted by the mixture's density (`scatter_aim`), so that
   light scattered in front of the stop finds the rear optics more often.
3. Update: pixel E_j = Σ_hit τ L_o, split by the part of the hit point's face, and by the
   gathered photon's path signature (its scatter faces, then the hit point's face).

The view map's backward samples also say which face the detector sees first from each pixel,
whatever its finish (`Film.faces`: critical faces); the photons, which faces they reach (lit).

The last-vertex rule (docs/bidirectional.md): every stray path is counted exactly once,
by its LAST scattering vertex before the detector. Broad (Lambertian, or a lobe ≥
`glossy_threshold_deg` half width): by the gather at a hit point. Narrow lobe or mirror:
by the photon itself reaching the detector (splatted into its pixel as the forward
estimator does), because a narrow lobe after the optics is nearly specular and photons
follow it efficiently while a density estimate would need an enormous number of photons
in its lobe. A narrow lobe with wide wings (black-paint ABg) is split by direction
(`gather_cores`): the gather counts the scatter outside its core, the photons the core. Paths with no scattering at all (direct image, pure ghosts)
are counted the same forward way when the scene turns `direct` or `ghosts` on, except the two-
(four-) reflection ghosts, which the deterministic routes count (`ghost_routes`).

A broad vertex whose last segment runs straight to the detector (a face behind the last lens that
the detector sees without glass: the housing, a field stop, a vane) is counted by its photon instead:
each photon there is connected to a random point of the detector (`connect`, light tracing), and the
backward rays that reach such a face straight from the detector make no hit point there.
Why: such a face is often lit in a small spot (off the field, the sun's image), which a gather sees
only through the few hit points near it; the connections see every photon of the spot (case 2: a
pass's spread 1.7 % → 0.6 %). Paths through the glass stay the gather's. With `connect_through_optics`
(off by default) a scatter in front of the optics is also connected through them to such a face
(`refracted_connection`), sharing those paths with the photons' own by the balance heuristic.

A mirror's coated face with a finish (`[assign] "surface:N"`) is counted by the photons too, a
decision, not an approximation: the tracer ends a ray there only with probability p (at least
the finish's albedo a; `Tracer.next_event`), backward rays included, so a hit point there would
be made for a share p of the samples with weight R·a/p and gather a share p of the photons; the
specular share the backward rays carry on (weight R(1 − a)/(1 − p), probability 1 − p) is
exactly the importance of the light the mirror reflects specularly. Every path is still counted
once: one whose last scattering vertex is the mirror by its photon on the detector, one
scattering at the mirror earlier by the gather at its last face. The cost: light scattered by a
mirror converges as in the forward estimator.

Photons are walked by the same code as the forward estimator (`walk.photon_walk`), photon k
of pass i being photon i·N + k of the run with its numbers keyed by that index; backward
sample j of pixel p in pass i draws from the stream keyed (seed, i, p, j). Pass i is the same
whichever worker runs it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.integrators.estimate import (
    AIMED_PASSES, UNAIMED_PASSES, EnergyLedger, Film, PassEstimate, face_tally,
    film_channels, phase_clock, phase_times, scattering_tags)
from lensmount.integrators.ghost_routes import ghost_routes_pass, route_reflections
from lensmount.integrators.paths import FaceTally
from lensmount.integrators.photon_mapping.connect import connect_to_detector
from lensmount.integrators.photon_mapping.photon_gather import (
    Gatherer, HitPoints, PhotonHits, gatherable_share, search_groups)
from lensmount.integrators.photon_mapping.photon_target import (
    aims_at_edge, edge_band, emission_component, guided_photons, pilot_check, pilot_check_diagnostics, tally_edge_flux)
from lensmount.integrators.photon_mapping.radius import FaceBoundaries, radius_caps, radius_scale
from lensmount.integrators.photon_mapping.refracted_connection import ThroughOptics, connections_through_optics, walk_share
from lensmount.integrators.photon_mapping.view_map import build_view_map, view_map_streams
from lensmount.integrators.registry import INTEGRATORS, NoParams
from lensmount.integrators.scatter_aim import aperture_targets
from lensmount.integrators.settings import EstimatorSettings
from lensmount.integrators.walk import Vertices, photon_walk
from lensmount.scene.scene import optical_faces
from lensmount.trace.tracer import FACE

_CACHE: dict[tuple, tuple] = {}


def _walk_share(scene, optics: ThroughOptics, step, rows: np.ndarray) -> np.ndarray:
    """(len(rows),) the balance heuristic's share of the photons `rows` of this step that came to their face
    through the optics alone from a scatter a connection through the optics starts from; 1 for the rest."""
    share = np.ones(len(rows))
    if step.came_from is None:
        return share
    ev, came = step.events, step.came_from
    k = np.flatnonzero(optics.starts(came.tag[rows], came.position[rows]) & (ev.reflections[rows] == 0))
    if len(k):
        r = rows[k]
        share[k] = walk_share(scene, optics.cells, optics.aim, came.take(r), ev.position[r], ev.direction[r],
                              ev.normal[r], ev.prim[r])
    return share


def _through_optics(scene, tracer, film, optics: ThroughOptics, ev, f, step, signature, core, seed, purpose) -> None:
    """Connect the scatters among photons `f` (at faces this step) through the optics to the faces the
    detector sees straight, and those on to the detector (`refracted_connection`)."""
    s = np.flatnonzero(optics.starts(ev.tag[f], ev.position[f]))
    if not len(s):
        return
    r = f[s]
    v = Vertices(ev.position[r], -ev.direction[r], ev.normal[r], ev.tag[r], ev.weight[r], ev.wavelength[r], ev.id[r])
    a = connections_through_optics(scene, tracer, optics.cells, optics.aim, v, step.scatterings, seed, purpose)
    if len(a.rows):
        connect_to_detector(scene, tracer, film, a.position, a.direction, a.normal, a.flux, a.tag, v.wavelength[a.rows],
                            film.paths.extend(signature[s][a.rows], a.tag), v.id[a.rows], step.scatterings, core, seed,
                            purpose + "/through-optics")


def gather_cores(bsdf_of_tag, threshold_deg: float = EstimatorSettings.glossy_threshold_deg,
                 min_share: float = EstimatorSettings.gathered_share) -> np.ndarray:
    """(n_tags,) per finish, the core of its lobe that photons count (direction cosines around the
    mirror direction); the gather takes the rest. 0: the whole lobe is gathered (a lobe at least
    threshold_deg wide, Lambertian); sin(threshold_deg): a glossy finish that still scatters at
    least min_share of its albedo outside that core at the incidences that occur
    (`photon_gather.gatherable_share`), e.g. ABg A = 2e-3, B = 1e-3, g = 2 (1.8° half width, 35 %
    outside 15°); inf: nothing gathered (mirrors, narrow lobes, absorbers).

    Why a split and not one class per finish: black-paint ABg data has a narrow core on top of
    wide wings. Routed by its half width alone it went entirely to the photons, and a 50 µm edge
    of it got no hit points (case 1 read 7.5e-4 ± 7.5e-4: 1 of 4 passes saw a photon)."""
    core = np.full(len(bsdf_of_tag), np.inf)
    cone = math.sin(math.radians(threshold_deg))
    for t, b in enumerate(bsdf_of_tag):
        if b is None or b.is_black or b.is_delta:
            continue
        if float(b.lobe_half_width_deg) >= threshold_deg:
            core[t] = 0.0
        elif gatherable_share(b, cone) >= min_share:
            core[t] = cone
    return core


def _scene_tables(scene, cap_mm: float = EstimatorSettings.radius_cap_mm,
                  normal_limit_deg: float = EstimatorSettings.normal_limit_deg):
    """Per-scene constants (radius caps, face boundaries), computed once per process."""
    key = (id(scene), id(scene.mesh), cap_mm, normal_limit_deg)  # the entry holds the scene: ids stay unique
    if key not in _CACHE:
        m = scene.mesh
        n_tags = len(m.tag_table)
        hw = radius_caps(m.vertices, m.triangles, m.tags, n_tags, cap_mm=cap_mm, max_normal_deg=normal_limit_deg)
        boundaries = FaceBoundaries(m.vertices, m.triangles, m.tags, n_tags)
        _CACHE.clear()
        _CACHE[key] = (scene, hw, boundaries)
    return _CACHE[key][1:]


class Bidirectional:
    """Bidirectional stochastic ray tracing (see the module docstring); the `Integrator` contract:
    `channels(scene)`, `run_pass(scene, tracer, pass_index, photons, seed, radius_scale=None)`, and its
    two halves `view_pass` (phase 1) and `photon_pass` (phases 2 and 3)."""

    name = "bidirectional"
    purpose = "photons"

    def __init__(self, settings: EstimatorSettings | None = None):
        self.settings = settings or EstimatorSettings()

    def channels(self, scene) -> list[str]:
        return film_channels(scene)

    def run_pass(self, scene, tracer, pass_index: int, photons: int, seed: int,
                 radius_scale: float | None = None) -> PassEstimate:
        """One complete, independent pass; radius_scale None: s_i of the settings' alpha schedule."""
        view = self.view_pass(scene, tracer, pass_index, seed, radius_scale)
        return self.photon_pass(scene, tracer, view, pass_index, photons, seed)

    def view_pass(self, scene, tracer, pass_index: int, seed: int, radius_scale: float | None = None) -> "ViewMap":
        """Phase 1 of pass `pass_index`: the view map, which does not depend on the source (`ViewMap`)."""
        cfg = self.settings
        scale = radius_scale_of(pass_index, cfg) if radius_scale is None else float(radius_scale)
        half_widths, boundaries = _scene_tables(scene, cfg.radius_cap_mm, cfg.normal_limit_deg)
        core = gather_cores(scene.bsdf_of_tag, cfg.glossy_threshold_deg, cfg.gathered_share)
        core[~scattering_tags(scene)] = np.inf  # scatter off: every mechanical face absorbs, nothing is gathered
        core[optical_faces(scene.mesh.tag_table)] = np.inf  # a scattering mirror: the photons count it (docstring)
        broad = np.isfinite(core)
        seen = face_tally(scene)
        # No hit points without a face to gather at (the plan's "scatter" is off).
        diagnostics: dict[str, float] = {}
        clock = phase_clock()
        hits = build_view_map(scene, tracer, scene.detector,
                              view_map_streams(seed, pass_index, scene.detector, cfg.samples_per_pixel,
                                               cfg.view_map_pitch), broad=broad,
                              half_widths=half_widths, radius_scale=scale, boundaries=boundaries,
                              samples_per_pixel=cfg.samples_per_pixel, pitch=cfg.view_map_pitch, mixture_c=cfg.mixture_c, pilot_seed=seed,
                              neighbours=cfg.neighbours, radius_cap_mm=cfg.radius_cap_mm, stats=diagnostics,
                              faces=seen, connected=cfg.connect_direct_view) if broad.any() else HitPoints.empty()
        groups = search_groups(hits)
        return ViewMap(int(pass_index), int(seed), scale, hits, groups, core, seen, diagnostics, phase_clock() - clock)

    def photon_pass(self, scene, tracer, view: "ViewMap", pass_index: int, photons: int, seed: int) -> PassEstimate:
        """Phases 2 and 3 of pass `pass_index` on its view map: photons from `scene`'s source, gathered at
        the view's hit points. `scene` may differ from the view's only in its source (`ViewMap`)."""
        if (view.pass_index, view.seed) != (int(pass_index), int(seed)):
            raise ValueError(f"the view map of pass {view.pass_index} (seed {view.seed}) given to pass {pass_index} "
                             f"(seed {seed}): a pass's photons are gathered at its own view map")
        cfg = self.settings
        scatters = scattering_tags(scene)
        core, hits, diagnostics = view.core, view.hits, dict(view.diagnostics)
        broad = np.isfinite(core)
        by_routes = route_reflections(scene, cfg)
        film, ledger = Film(scene, by_routes, seen=view.seen), EnergyLedger()

        # Phase 2: photons, walked as in the forward estimator; at every scattering face they
        # deposit into the hit points there before they scatter on. A thin diaphragm edge gets
        # most of them aimed at it (the pilot's band, once per process; Φ by the mixture density).
        clock = phase_clock()
        # per film (its paths get the gather's sums), at the view map's search trees: the gather's time
        gatherer = Gatherer(hits, scene.bsdf_of_tag, max_normal_deg=cfg.normal_limit_deg,
                            detector_z=scene.detector.z, core_of_tag=np.where(broad, core, 0.0), paths=film.paths,
                            groups=view.groups)
        connects = cfg.connect_direct_view  # the view map made no hit point where the detector sees a face straight
        gather_s = phase_clock() - clock
        met = len(hits.weight) or diagnostics.get("view_map_direct_hit_points", 0)  # broad faces the detector sees
        aim = bool(cfg.edge_photons and met and aims_at_edge(scene, broad))
        band = edge_band(scene, tracer, broad, seed) if aim else None
        rays = guided_photons(scene, band, seed, self.purpose, int(pass_index) * int(photons), photons)
        # summed over passes in the summary: how many passes aimed, and how many would have but the
        # pilot found the edge too rarely lit (uniform emission: correct, far slower; the plan says so)
        diagnostics[AIMED_PASSES] = float(band is not None)
        diagnostics[UNAIMED_PASSES] = float(aim and band is None)
        if band is not None:
            diagnostics.update(pilot_check_diagnostics(pilot_check(scene, tracer, broad, seed)))
        # A scatter whose lobe the gather counts whole leans toward the optics ahead, where another face can
        # still scatter the photon (case 1's lone edge: its photons' further way counts for nothing, aimed or not).
        apertures = aperture_targets(scene)
        aimable = (core == 0) & (np.count_nonzero(scatters) - scatters > 0)
        apertures = apertures.only(aimable) if apertures is not None else None
        optics = (ThroughOptics.of_scene(scene, core, scatters, apertures)
                  if connects and cfg.connect_through_optics and not tracer.fresnel_branch else None)
        for step in photon_walk(scene, tracer, rays, seed, self.purpose, cfg, film, ledger, gathered=core,
                                aim=apertures):
            ev = step.events
            at_face = ev.kind == FACE
            at_face[at_face] &= scatters[ev.tag[at_face]] & (ev.weight[at_face] > 0)
            if band is not None and step.scatterings == 0:  # the edge is the only scatterer (`aims_at_edge`)
                tally_edge_flux(diagnostics, emission_component(seed, self.purpose, ev.id[at_face]), ev.weight[at_face])
            if at_face.any() and (len(hits.weight) or connects):
                start = phase_clock()
                f = np.flatnonzero(at_face)
                signature = film.paths.extend(step.signature[f], ev.tag[f])
                gatherer.gather(PhotonHits(ev.position[f], ev.direction[f], ev.normal[f], ev.weight[f],
                                           ev.tag[f].astype(np.int32), ev.wavelength[f], signature))
                if connects:  # every pass, whether or not its view map has direct hit points (unbiased)
                    c = np.flatnonzero(broad[ev.tag[f]])
                    flux = ev.weight[f][c]
                    if optics is not None:
                        flux = flux * _walk_share(scene, optics, step, f[c])
                    connect_to_detector(scene, tracer, film, ev.position[f][c], ev.direction[f][c], ev.normal[f][c],
                                        flux, ev.tag[f][c], ev.wavelength[f][c], signature[c],
                                        ev.id[f][c], step.scatterings, core, seed, self.purpose)
                    if optics is not None:
                        _through_optics(scene, tracer, film, optics, ev, f, step, signature, core, seed, self.purpose)
                gather_s += phase_clock() - start
        diagnostics.update(phase_times(view_map=view.seconds, gather=gather_s,
                                       walk=phase_clock() - clock - gather_s))

        if by_routes:  # the ghosts channel's two- (four-) reflection light, deterministically
            clock = phase_clock()
            ghost_routes_pass(scene, tracer, film, pass_index, seed, cfg.ghost_rays_across)
            diagnostics.update(phase_times(ghost_routes=phase_clock() - clock))

        # Phase 3: the update — the gather's image plus the photons the film counted.
        _, parts_g = gatherer.image(film.detector.shape, film.channel_of_tag, len(film.channels))
        film.add_images(parts_g)
        film.largest.add(gatherer.largest.values * film.detector.pixel_area)
        estimate = film.estimate(photons, ledger, diagnostics)
        # The same pass with every gather radius on the ladder (only the gathered part changes): the bias estimate.
        estimate.radius_scale = view.radius_scale
        estimate.part_flux_ladder = (estimate.part_flux - parts_g.sum(axis=(1, 2)) * film.detector.pixel_area
                                     + gatherer.part_flux_ladder(film.channel_of_tag, len(film.channels))
                                     * film.detector.pixel_area)
        return estimate


@dataclass
class ViewMap:
    """Phase 1 of a bidirectional pass: all of it that does not depend on the source.

    The backward samples start on the detector and their numbers are keyed by (seed, pass, pixel,
    sample); where they stop (broad faces), the radii (the pass's s_i, r_0 from the hit points
    themselves) and the edge target's pilot (backward rays from the detector, `targets.learned_rim`)
    read the mesh, the finishes, the effects, the optics and the detector, never the source. So one
    view map serves the photons of any source of the same scene (`Bidirectional.photon_pass`; `pst`
    gathers every angle's photons of pass i at pass i's view map). What does read the source stays
    in the photon phase: the photons' aim at the diaphragm edge (`photon_target.edge_band`, a pilot
    of photons), the ghost routes, the emission.

    pass_index, seed : the pass it belongs to
    radius_scale : s_i, the pass's gather radius relative to r_0
    hits : the hit points with their radii (none when nothing is gathered)
    groups : their search trees (`photon_gather.search_groups`), shared by every source's gather
    core : (n_tags,) per face the lobe core the photons count (`gather_cores`; inf: nothing gathered)
    seen : the faces the detector sees first from each pixel (`paths.FaceTally`, the film's `seen`)
    diagnostics : the backward samples traced and lost (`view_map.build_view_map`'s stats)
    seconds : (wall, CPU) seconds it took (the plan's view-map phase)
    """

    pass_index: int
    seed: int
    radius_scale: float
    hits: HitPoints
    groups: dict
    core: np.ndarray
    seen: FaceTally
    diagnostics: dict[str, float]
    seconds: np.ndarray


def radius_scale_of(pass_index: int, settings: EstimatorSettings) -> float:
    """s_i of pass i under the settings' radius schedule."""
    return radius_scale(pass_index, settings.alpha)


@INTEGRATORS.register("bidirectional", NoParams)
def make_bidirectional(params: NoParams, settings: EstimatorSettings) -> Bidirectional:
    """Bidirectional stochastic ray tracing: photons gathered at the view map's hit points."""
    return Bidirectional(settings)


def bidirectional_pass(scene, tracer, n_photons: int, seed: int, pass_index: int, radius_scale: float,
                       **settings) -> PassEstimate:
    """`Bidirectional(EstimatorSettings(**settings)).run_pass(...)` at a given radius scale (scripts, tests)."""
    return Bidirectional(EstimatorSettings(**settings)).run_pass(scene, tracer, pass_index, n_photons, seed,
                                                                 radius_scale=radius_scale)


__all__ = ["Bidirectional", "make_bidirectional", "ViewMap", "bidirectional_pass", "gather_cores", "radius_scale_of"]
