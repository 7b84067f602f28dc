"""The `ghosts` channel of a pass from deterministic ghost routes instead of the stochastic branch.

The channel keeps its meaning: light that reaches the detector unscattered after at least one
Fresnel reflection. It is split by the number of reflections. Routes of 2 (ghost order 2) or 2
and 4 (order 3) reflections are traced deterministically (`trace.ghosts`: every route, the real
reflectance per ray and wavelength, the mount's walls); the photons of the walk that arrive
unscattered with exactly those counts are left to them (ledger `detector_ghost_routes`), those
with more reflections still go into the channel as photons. The tracer keeps its reflection
branch: light reflected at glass that then scatters belongs to the part channels, not here.

Why (benchmarks/bench_ghosts.py, uncoated Cooke triplet, seconds to 1 % on this channel): photons
only 997 s; a pass with the routes 7.4 s (134×: the photons' four-reflection share is what is left);
the routes alone 0.5 s for the two-reflection part (1 900×). A photon makes a two-reflection ghost
with probability ~R² ≈ 2e-3; a route traces every such path of a lattice point at once. The double
Gauss with MgF2 coatings: 7 534 s, 209 s (36×), 9.7 s (776×).

The error bar is honest: each pass traces the routes on a lattice whose offset (and the sun's
direction sequence) is shifted by uniform random numbers keyed by (seed, pass), randomised
quasi-Monte Carlo. Every pass is then an unbiased, independent estimate, so the spread of the
passes — the one error bar the accumulator computes for every channel — is the stratification
error of the lattice, and it shrinks as passes accumulate. Same seed, same numbers.
"""

from __future__ import annotations

from lensmount.trace.ghosts import Walls, launch, reflecting, reflections_of_order, route_count, trace_routes
from lensmount.physics.sampler import stream

PURPOSE = "ghost-routes"


MAX_FOUR_REFLECTION_ROUTES = 400  # beyond this the photons carry the four-reflection ghosts (see below)


def route_reflections(scene, settings) -> tuple[int, ...]:
    """The Fresnel reflection counts the routes count for `scene` ((2,) or, order 3, (2, 4)); () when
    the stochastic branch keeps the whole channel (ghosts off, deterministic routes off in the
    settings, a source at a finite distance: the routes launch a collimated lattice, or fewer than
    two surfaces that can reflect: then no ghost exists at all).

    Four-reflection routes cost per route, not per ray (~2 ms of array work per surface crossing):
    the Cooke triplet's 190 take 3.6 s a pass at 33 rays across, against 0.6 s for its 15 pairs,
    and replace photons that need ~7 s to 1 %; the double Gauss's 1 695 take 85 s a pass for
    0.2 % of its ghost light. Beyond MAX_FOUR_REFLECTION_ROUTES the photons keep them."""
    reflects = reflecting(scene)
    if not (scene.effects.ghosts and settings.ghost_routes) or reflects.sum() < 2:
        return ()
    if not scene.source.at_infinity:
        return ()
    most = reflections_of_order(scene.effects.ghost_order)
    if most >= 4 and route_count(reflects, 4) > MAX_FOUR_REFLECTION_ROUTES:
        most = 2
    return tuple(range(2, most + 1, 2))


def ghost_routes_pass(scene, tracer, film, pass_index: int, seed: int, rays_across: int) -> None:
    """One pass of the deterministic routes of `film.by_routes` reflections into `film`
    (`Film.deposit_route`: the ghosts channel, each route's path signature and flux)."""
    det = scene.detector
    shift = stream(seed, PURPOSE, pass_index).random(4)
    walls = Walls(tracer)
    rays = launch(scene, rays_across, shift, walls)
    for a in trace_routes(scene, rays, max(film.by_routes), walls):
        pix = det.pixel_of(a.points)
        on = pix >= 0
        if on.any():
            film.deposit_route(a.route, pix[on], a.flux[on], a.wavelength[on])


__all__ = ["route_reflections", "ghost_routes_pass", "PURPOSE", "MAX_FOUR_REFLECTION_ROUTES"]
