"""The effects planner: the scene's `[effects]` → the work the integrators do, as data.

`plan(scene)` decides once per run, before any photon, what is traced and what is not, and
why. Every decision is exact: a skipped piece of work is one that provably adds nothing to
any channel the run reports, so a restricted run and a run with everything on agree on the
channels they share (tests/integrators/test_plan_effects.py measures it).

- *Scatter.* Photons scatter on at the faces `walk.scattering_tags` gives (a non-black
  finish, named by `effects.scatter`); the view map makes hit points only there. Every other
  mechanical face ends the photon where it lands.
- *Scatter at a mirror.* A mirror's coated face with a finish (`"surface:N"`) among the
  scatterers: the tracer ends a ray there with probability p = max(a, 0.1) (a(wi): the finish's
  albedo; weight R·a/p) and reflects it specularly otherwise (weight R(1 − a)/(1 − p);
  `Tracer.next_event`); its own line says so. A black
  finish, or one `[effects] scatter` leaves out, leaves the mirror specular (R), as without one.
- *Where a photon ends.* At the first event after which no counted path is possible:
  an absorber, a face outside the scatterers, the detector, or leaving the assembly. This is
  provably safe, and nothing earlier is: a counted path is a sequence of scatterings at the
  scatterers (`scatter`), or no scattering at all (`direct`, `ghosts`), so a face outside
  the set ends every path through it. Before its next event a photon may still reach a
  scatterer through glass (refraction bends it anywhere behind a lens, and a scatterer seen
  in a lens reflection is reachable too), so no geometric test may end it earlier.
- *Reflection branch at glass.* Only with ghosts on and a surface that reflects (not every
  surface perfect-ar). Without it the ray transmits with weight T = 1 − R and R goes to the
  ledger's `glass`.
- *One wavelength.* When nothing along any path depends on the wavelength, tracing W
  wavelengths only dilutes the gather (a hit point gathers photons of its own wavelength):
  the planned scene traces one, with the detector's response replaced by its mean over the
  source's spectrum, Σ p_w r_w, which is what the W-wavelength run converges to. That is so
  when every refractive index the tracer reads (both sides of every optical surface, the solid
  behind every face) is the same at every wavelength — no dispersion —, so is the glass's bulk
  absorption when `effects.absorption` is on, and no coating's R
  depends on the wavelength at a given index (perfect-ar, uncoated, constant R; not the
  MgF2 quarter wave). BSDFs and sources here have no wavelength dependence of their own.
  A real glass lens disperses: a scene with glass keeps all its wavelengths.
- *Direct.* Skipped when the source's nearest edge lies more than `DIRECT_MARGIN_DEG` beyond
  the field the detector can image (`Scene.field_of_view_deg`: the larger of the lens's
  field and the detector's half diagonal seen through the focal length). Unscattered light
  at that angle would need that much distortion to land on the detector; the direct channel
  reads 0 with nothing spent on it.

`Plan.as_dict(times)` is the `plan` block of summary.json: what ran, what was skipped and why,
and the time each phase took (`time/<phase>` in the passes' diagnostics).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from lensmount.integrators.estimate import (
    AIMED_PASSES, EDGE_FLUX, EDGE_FLUX_SQ, PILOT_MISSED, PILOT_MISSED_AFTER, PILOT_RINGS_ADDED, TIME_PREFIX,
    UNAIMED_PASSES)
from lensmount.integrators.photon_mapping.photon_target import (
    CHECK_MISSED, COMPONENTS, MIN_HITS, PILOT_PHOTONS, PILOT_ROUNDS)
from lensmount.integrators.walk import scattering_tags
from lensmount.integrators.ghost_routes import MAX_FOUR_REFLECTION_ROUTES, route_reflections
from lensmount.integrators.settings import EstimatorSettings
from lensmount.scene.scene import Scene, optical_faces
from lensmount.trace.ghosts import reflecting, route_count
from lensmount.trace.tracer import MIRROR_SCATTER_MIN_SHARE

DIRECT_MARGIN_DEG = 5.0  # beyond the imaged field, as the mount's exclusion angle (field + 5°)
HEAVY_COMPONENT_SPREAD = 0.25  # a uniform or wide component alone spreading a pass's edge flux by this: heavy tails
_WAVELENGTH_FREE_COATINGS = ("perfect-ar", "uncoated", "constant")


@dataclass(frozen=True)
class Decision:
    """One line of the plan: `what` ran (or was skipped) and why."""

    what: str
    ran: bool
    why: str


@dataclass(eq=False)
class Plan:
    """What a run traces.

    scene : the Scene the integrators get (the input scene, or it with one wavelength)
    scatters : (n_tags,) bool, faces where photons scatter on (and hit points may be made)
    reflect_at_glass : the tracer follows Fresnel reflections (ghosts on, some surface reflects)
    direct : unscattered light can reach the detector and is counted
    decisions : the lines of the plan, in the order they are printed
    """

    scene: Scene
    scatters: np.ndarray
    reflect_at_glass: bool
    direct: bool
    decisions: list[Decision] = field(default_factory=list)

    def as_dict(self, diagnostics: dict | None = None) -> dict:
        """The summary.json block: ran / skipped (what, why) and seconds per phase."""
        times = {k[len(TIME_PREFIX):]: round(float(v), 3) for k, v in sorted((diagnostics or {}).items())
                 if k.startswith(TIME_PREFIX)}
        ran = [{"what": d.what, "why": d.why} for d in self.decisions if d.ran]
        aimed = int((diagnostics or {}).get(AIMED_PASSES, 0))
        if aimed:
            ran.append({"what": "photons aimed at the diaphragm edge",
                        "why": f"{aimed} pass(es): most photons start in the pilot's band in the entrance pupil, "
                               "each weighted by the mixture density (unbiased)",
                        **edge_flux_components(diagnostics or {}, aimed)})
        skipped = [{"what": d.what, "why": d.why} for d in self.decisions if not d.ran]
        unaimed = int((diagnostics or {}).get(UNAIMED_PASSES, 0))
        if unaimed:
            skipped.append({"what": "photons aimed at the diaphragm edge",
                            "why": f"{unaimed} pass(es): the pilot found fewer than {MIN_HITS} of its photons (up to "
                                   f"{PILOT_ROUNDS * PILOT_PHOTONS:,}) aimed at the entrance pupil's rim "
                                   "meeting the edge, so photons start uniformly on the source disc (unbiased, "
                                   "but the edge's light is rare: expect a large error bar or no signal)"})
        return {"ran": ran,
                "skipped": skipped,
                "time_s": times}


def edge_flux_components(diagnostics: dict, passes: int) -> dict:
    """Which part of the aimed photons' mixture carried the edge's light: per component (uniform on the
    disc, wide band, aimed ring) its share of the flux first arriving at the edge and the relative
    spread it alone gives a pass, √(Σ Φ² / passes) / (edge flux per pass). A uniform or wide share
    carried by few heavy photons (spread ≥ HEAVY_COMPONENT_SPREAD) makes passes heavy-tailed: the
    ring misses part of the lit edge; `warning` says so. `pilot_check`: what the
    pilot's check found (`photon_target.PilotCheck`); a ring that missed more than CHECK_MISSED of the
    light its check photons brought to the edge is a `note` (it was mended with rings fitted to those
    hits) and, when the mended rings still miss that much, a `warning`."""
    if passes < 1:
        return {}
    out = _pilot_check(diagnostics, passes)
    total = sum(diagnostics.get(EDGE_FLUX + c, 0.0) for c in COMPONENTS)
    if not total > 0:
        return out
    per_pass = total / passes
    share = {c: diagnostics.get(EDGE_FLUX + c, 0.0) / total for c in COMPONENTS}
    spread = {c: math.sqrt(diagnostics.get(EDGE_FLUX_SQ + c, 0.0) / passes) / per_pass for c in COMPONENTS}
    out.update({"edge_flux_share": {c: round(share[c], 6) for c in COMPONENTS},
                "edge_flux_pass_spread": {c: round(spread[c], 6) for c in COMPONENTS}})
    heavy = [c for c in ("uniform", "wide") if spread[c] >= HEAVY_COMPONENT_SPREAD]
    if heavy:
        out["warning"] = "; ".join(w for w in (out.get("warning"), " and ".join(
            f"the {c} photons ({100 * share[c]:.1f} % of the edge's light, {spread[c]:.2f} of a pass in spread)"
            for c in heavy) + " carry the edge's light in few heavy photons: the learned ring misses part of the lit "
                              "edge, the passes are heavy-tailed, the error bar is not to be trusted and the run does "
                              "not count as converged") if w)
    return out


def _pilot_check(diagnostics: dict, passes: int) -> dict:
    """The plan line's `pilot_check` (and its note or warning) from the passes' PILOT_* diagnostics."""
    if PILOT_MISSED not in diagnostics:
        return {}
    missed, after = diagnostics[PILOT_MISSED] / passes, diagnostics.get(PILOT_MISSED_AFTER, 0.0) / passes
    added = diagnostics.get(PILOT_RINGS_ADDED, 0.0) / passes
    out = {"pilot_check": {"edge_light_outside_ring": round(missed, 6), "rings_added": round(added, 3),
                           "edge_light_outside_after": round(after, 6)}}
    if missed > CHECK_MISSED:
        out["note"] = (f"the pilot's fitted ring missed {100 * missed:.1f} % of the edge's light its check photons "
                       f"(drawn over the whole pupil rim) found; {added:g} ring(s) fitted to those hits were added, "
                       f"{100 * after:.1f} % outside after")
    if after > CHECK_MISSED:
        out["warning"] = (f"the aimed rings miss {100 * after:.1f} % of the edge's light the pilot's check found "
                          f"(more than {100 * CHECK_MISSED:g} %): it comes in few heavy photons, the passes are "
                          "heavy-tailed and the run does not count as converged")
    return out


def plan(scene, settings=None) -> Plan:
    """The plan of a run on `scene` with the estimator `settings` (default EstimatorSettings(); see the
    module docstring)."""
    scatters = scattering_tags(scene)
    decisions = [_scatter(scene, scatters), *_mirrors(scene, scatters), _photon_ends(scene, scatters)]
    reflect = bool(scene.effects.ghosts) and bool(reflecting(scene).any())  # as `Tracer.fresnel_branch`
    decisions.append(_ghosts(scene, reflect))
    if reflect:
        decisions.append(_ghost_routes(scene, settings or EstimatorSettings()))
    direct, why = _direct(scene)
    decisions.append(Decision("direct", direct, why))
    traced, decision = _wavelengths(scene)
    decisions.append(decision)
    return Plan(traced, scatters, reflect, direct, decisions)


def _faces(scene, mask: np.ndarray) -> str:
    """'diaphragm (diaphragm-edge), housing (mount)': the parts and roles of the tags in mask."""
    seen: dict[str, list[str]] = {}
    for k in np.flatnonzero(mask):
        t = scene.mesh.tag_table[k]
        roles = seen.setdefault(t.part, [])
        if t.role not in roles:
            roles.append(t.role)
    return ", ".join(f"{p} ({'/'.join(r)})" for p, r in seen.items()) or "none"


def _scatter(scene, scatters: np.ndarray) -> Decision:
    e = scene.effects
    if not e.scatter:
        return Decision("scatter", False, "scatter = false: every mechanical face absorbs, no hit points")
    if not scatters.any():
        return Decision("scatter", False, "no face the scene lets scatter has a scattering finish (all absorbers)"
                        + (f" among {', '.join(e.scatterers)}" if e.scatterers else ""))
    named = f"the faces {', '.join(e.scatterers)} name" if e.scatterers else "every face with a scattering finish"
    mirrors = scatters & optical_faces(scene.mesh.tag_table)  # no hit points there: the lines below say why
    return Decision("scatter", True, f"photons scatter and hit points are made on {named}: "
                    f"{_faces(scene, scatters & ~mirrors)}" + ("; mirrors: below" if mirrors.any() else ""))


def _mirrors(scene, scatters: np.ndarray) -> list[Decision]:
    """One line per mirror face the scene gives a finish: scattered on top of R, or specular only."""
    out = []
    for k in np.flatnonzero(optical_faces(scene.mesh.tag_table)):
        b = scene.bsdf_of_tag[k]
        if b is None:
            continue
        t = scene.mesh.tag_table[k]
        what = f"scatter at mirror surface {t.surface + 1} ({t.part})"
        finish = f"finish '{scene.finish_of_tag[k]}'" if scene.finish_of_tag else "its finish"
        if scatters[k]:
            out.append(Decision(what, True, f"{finish} (TIS {b.tis:.3g}): the tracer reflects R(1 − a) specularly "
                                "and ends R·a on the face for the walk to scatter (a: the finish's albedo at each "
                                f"incidence; at least {MIRROR_SCATTER_MIN_SHARE:g} of the rays take that branch); "
                                "bidirectional counts that light by its photons (no hit points on a "
                                "mirror)"))
        else:
            out.append(Decision(what, False, f"{finish} " + ("is black" if b.is_black else
                                                             "is not among the scatterers [effects] names")
                                + ": the mirror reflects specularly only (R)"))
    return out


def _photon_ends(scene, scatters: np.ndarray) -> Decision:
    mechanical = np.array([t.role != "optical" for t in scene.mesh.tag_table], bool)
    black = np.array([b is not None and b.is_black for b in scene.bsdf_of_tag], bool)
    outside = mechanical & ~black & ~scatters
    why = (f"photons end where no counted path goes on: {int((mechanical & black).sum())} absorbing faces"
           + (f", {int(outside.sum())} faces outside the scatterers ({_faces(scene, outside)})" if outside.any() else "")
           + ", the detector, leaving the assembly")
    return Decision("photon walk past non-scatterers", False, why)


def _ghosts(scene, reflect: bool) -> Decision:
    e = scene.effects
    if not e.ghosts:
        return Decision("ghosts (reflection branch at glass)", False,
                        "ghosts = false: rays transmit with weight T = 1 − R; R goes to the ledger's 'glass'")
    if not reflect:
        return Decision("ghosts (reflection branch at glass)", False,
                        "every optical surface is perfect-ar (R = 0): no ghost light exists, the channel reads 0")
    return Decision("ghosts (reflection branch at glass)", True,
                    f"order {e.ghost_order}: Fresnel reflections followed with probability R")


def _ghost_routes(scene, settings) -> Decision:
    what = "ghosts: deterministic routes"
    counts = route_reflections(scene, settings)
    if not counts:
        why = ("ghost_routes = false" if not settings.ghost_routes else
               "the source is at a finite distance (routes launch a beam from infinity)"
               if not scene.source.at_infinity else "fewer than two surfaces reflect")
        return Decision(what, False, why + ": photons carry the whole ghosts channel")
    reflects = reflecting(scene)
    routes = " and ".join(f"{route_count(reflects, n)} routes of {n} reflections" for n in counts)
    why = (f"{routes} traced each pass on a randomised lattice ({settings.ghost_rays_across} across the first "
           "surface, real Fresnel R per ray); photons carry the rest of the channel")
    if scene.effects.ghost_order == 3 and 4 not in counts:
        why += (f"; the {route_count(reflects, 4)} four-reflection routes (over {MAX_FOUR_REFLECTION_ROUTES}) "
                "are left to the photons")
    return Decision(what, True, why)


def source_edge_deg(source) -> float:
    """Off-axis angle of the source's edge nearest the axis, degrees."""
    return float(source.off_axis_deg) - math.degrees(float(source.half_angle_rad))


def _direct(scene) -> tuple[bool, str]:
    if not scene.effects.direct:
        return False, "direct = false: unscattered light on the detector is not counted"
    # a source at a finite distance: its off_axis_deg / half_angle_rad are seen from the entrance pupil
    edge, fov = source_edge_deg(scene.source), float(scene.field_of_view_deg)
    if edge > fov + DIRECT_MARGIN_DEG:
        return False, (f"the source's nearest edge ({edge:.2f}°) lies beyond what the detector images "
                       f"({fov:.2f}° + {DIRECT_MARGIN_DEG:g}°): the channel reads 0")
    return True, f"the source ({edge:.2f}°) lies within {fov:.2f}° + {DIRECT_MARGIN_DEG:g}° of what the detector images"


def dispersion_free(scene) -> bool:
    """Nothing the tracer reads depends on the wavelength (see the module docstring)."""
    def flat(a) -> bool:
        a = np.asarray(a, np.float64)
        return bool(np.all(a == a[..., :1]))

    absorbs = bool(scene.effects.absorption)
    return (all(flat(s.n_before) and flat(s.n_after) and (s.mirror or s.coating.kind in _WAVELENGTH_FREE_COATINGS)
                and (not absorbs or (flat(s.absorption_before) and flat(s.absorption_after)))
                for s in scene.optical) and flat(scene.solid_index_of_tag)
            and (not scene.detector.medium_index or flat(scene.detector.medium_index))
            and (not absorbs or flat(scene.solid_absorption_of_tag)))


def _wavelengths(scene: Scene) -> tuple[Scene, Decision]:
    wl = np.asarray(scene.wavelengths_um, np.float64)
    what = "one wavelength for all"
    if len(wl) == 1:
        return scene, Decision(what, True, f"the scene has one wavelength ({wl[0]:.4f} µm)")
    names = ", ".join(f"{w:.4f}" for w in wl)
    if not dispersion_free(scene):
        return scene, Decision(what, False, f"{len(wl)} wavelengths ({names} µm) traced: a refractive index "
                               "or a coating changes with the wavelength")
    p = np.asarray(scene.source.wavelength_weights, np.float64)
    p = p / p.sum()
    keep = int(np.argmax(p))
    response = scene.detector.spectral_weight
    detector = scene.detector if response is None else \
        replace(scene.detector, spectral_weight=(float(np.dot(p, np.asarray(response, np.float64))),))
    if scene.detector.medium_index:
        detector = replace(detector, medium_index=scene.detector.medium_index[keep:keep + 1])
    one = replace(scene, wavelengths_um=wl[keep:keep + 1], detector=detector,
                  source=replace(scene.source, wavelength_weights=(1.0,)),
                  optical=[replace(s, n_before=np.atleast_1d(s.n_before)[keep:keep + 1],
                                   n_after=np.atleast_1d(s.n_after)[keep:keep + 1],
                                   absorption_before=np.atleast_1d(s.absorption_before)[keep:keep + 1],
                                   absorption_after=np.atleast_1d(s.absorption_after)[keep:keep + 1])
                           for s in scene.optical],
                  solid_index_of_tag=np.asarray(scene.solid_index_of_tag)[:, keep:keep + 1],
                  solid_absorption_of_tag=np.asarray(scene.solid_absorption_of_tag)[:, keep:keep + 1])
    return one, Decision(what, True, f"traced at {wl[keep]:.4f} µm for all {len(wl)} ({names} µm): no index or "
                         "coating changes with the wavelength; the detector response is its mean over the spectrum")


__all__ = ["Plan", "Decision", "plan", "dispersion_free", "source_edge_deg", "DIRECT_MARGIN_DEG"]
