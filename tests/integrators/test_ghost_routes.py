"""Deterministic ghost routes inside a pass: unbiased randomised lattices, path codes, no work without ghosts."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.loop.ghosts import ghost_report  # noqa: E402
from lensmount.integrators.estimate import Film, film_channels  # noqa: E402
from lensmount.integrators.forward import Forward  # noqa: E402
from lensmount.integrators.ghost_routes import ghost_routes_pass, route_reflections  # noqa: E402
from lensmount.analysis.paths import PathSums, ghost_pairs  # noqa: E402
from lensmount.integrators.paths import ghost_code, ghost_of  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


def test_route_deposits_carry_the_photons_ghost_code_and_ghost_pairs_split_the_channel():
    """A route's deposits are the path a photon on it would make (reflection count, first two surfaces);
    `ghost_pairs` over a few passes sums to the ghosts channel and names the singlet's one pair."""
    scene = singlet_barrel(make_bsdf("absorber"), off_axis_deg=2.0, ghosts=True, coating="uncoated",
                           detector_mm=60.0)
    tracer = Tracer(scene)
    sums, channel = PathSums(), []
    for i in range(3):
        estimate = Forward().run_pass(scene, tracer, i, 2000, 1)
        sums.add(estimate.paths, estimate.faces)
        channel.append(estimate.part_flux[estimate.part_names.index("ghosts")])
    codes = {c for cs in sums.events.values() for c in cs}
    assert int(ghost_code(np.array([2]), np.array([1]), np.array([0]))[0]) in codes  # S2 then S1, 0-based
    assert ghost_of(int(ghost_code(np.array([2]), np.array([1]), np.array([0]))[0])) == (2, 1, 0)
    aperture = scene.entrance_pupil_area_mm2 * scene.source.entering_fraction
    table = ghost_pairs(sums, aperture)
    assert table[0]["surfaces"] == [2, 1] and table[0]["reflections"] == 2 and table[0]["std_error"] is not None
    assert sum(r["fraction"] for r in table) == pytest.approx(np.mean(channel) / aperture, rel=1e-9)


def _ghost_flux(scene, tracer, pass_index, rays_across):
    film = Film(scene, route_reflections(scene, EstimatorSettings()))
    ghost_routes_pass(scene, tracer, film, pass_index, 5, rays_across)
    return film.estimate(1, _Ledger()).part_flux[film_channels(scene).index("ghosts")]


class _Ledger:
    def as_dict(self):
        return {}


def test_randomised_lattices_are_unbiased_and_their_spread_is_the_error():
    """A coarse lattice (31 across the pupil) shifted at random per pass: the mean of 12 passes agrees
    with a fine centred lattice (151 across) within its own error bar, which is small (the test has
    teeth), and the passes differ (they are not one lattice repeated). The barrel vignettes most of
    the ghost: the lattice's error is its edge."""
    scene = singlet_barrel(make_bsdf("absorber"), off_axis_deg=2.0, ghosts=True, coating="uncoated",
                           detector_mm=60.0)
    tracer = Tracer(scene)
    reference = ghost_report(scene, tracer, rays_across=151)
    aperture = scene.entrance_pupil_area_mm2 * scene.source.entering_fraction
    passes = np.array([_ghost_flux(scene, tracer, i, 31) for i in range(12)]) / aperture
    mean, se = passes.mean(), passes.std(ddof=1) / math.sqrt(len(passes))
    assert reference.total_fraction > 0 and np.ptp(passes) > 0
    assert mean == pytest.approx(reference.total_fraction, abs=4 * se)
    assert se < 0.03 * mean  # 11 across: 12 %; 21: 3.2 %; 31: 1.3 % (measured)


def test_perfect_ar_means_no_ghost_route_work(monkeypatch):
    """Ghosts on, every surface perfect AR: the tracer draws no reflection branch, no route is traced,
    the ghosts channel reads 0 and no ghost path is in the pass's paths."""
    import lensmount.integrators.ghost_routes as routes
    import lensmount.trace.tracer as tracer_module

    def fail(*args, **kwargs):
        raise AssertionError("ghost work for a lens that cannot reflect")

    monkeypatch.setattr(routes, "trace_routes", fail)
    monkeypatch.setattr(routes, "launch", fail)
    monkeypatch.setattr(tracer_module, "ray_streams", fail)  # the Fresnel branch's random numbers
    scene = singlet_barrel(make_bsdf("absorber"), off_axis_deg=2.0, ghosts=True, coating="perfect-ar")
    assert route_reflections(scene, EstimatorSettings()) == ()
    tracer = Tracer(scene)
    assert not tracer.fresnel_branch
    estimate = Forward().run_pass(scene, tracer, 0, 2000, 1)
    assert estimate.part_flux[estimate.part_names.index("ghosts")] == 0.0
    assert all(c >= 0 for codes in estimate.paths.events.values() for c in codes)  # no ghost path at all


def test_route_count_enumerates_the_alternating_routes():
    """Against brute force: sequences reflecting at j1 > i1 < j2 > i2 … among the surfaces that reflect."""
    import itertools

    from lensmount.trace.ghosts import route_count

    rng = np.random.default_rng(3)
    for s in (2, 4, 7):
        reflects = rng.random(s) < 0.8
        for n in (2, 4):
            brute = sum(all(reflects[k] for k in seq) and all((a > b) if i % 2 == 0 else (a < b)
                                                               for i, (a, b) in enumerate(zip(seq, seq[1:])))
                        for seq in itertools.product(range(s), repeat=n))
            assert route_count(reflects, n) == brute
    assert route_count(np.ones(6, bool), 2) == 15 and route_count(np.ones(2, bool), 4) == 1


def test_order_3_routes_carry_the_four_reflection_ghost_and_the_plan_says_so():
    """Singlet, order 3: the pair and the one four-reflection route (S2, S1, S2, S1) come from the routes
    (path codes of 2 and 4 reflections), and the plan names them; photons on them are left out."""
    from dataclasses import replace

    from lensmount.integrators.plan import plan

    base = singlet_barrel(make_bsdf("absorber"), off_axis_deg=0.5, ghosts=True, coating="R=0.3", detector_mm=60.0)
    scene = replace(base, effects=replace(base.effects, ghost_order=3))
    assert route_reflections(scene, EstimatorSettings()) == (2, 4)
    estimate = Forward().run_pass(scene, Tracer(scene), 0, 3000, 1)
    codes = {c for cs in estimate.paths.events.values() for c in cs if c < 0}
    assert {ghost_of(c)[:2] for c in codes} >= {(2, 1), (4, 1)}
    assert estimate.ledger["detector_ghost_routes"] > 0  # photons on those paths, counted by the routes
    line = next(d for d in plan(scene).decisions if d.what == "ghosts: deterministic routes")
    assert line.ran and "1 routes of 2 reflections and 1 routes of 4 reflections" in line.why


def test_the_lattice_spans_the_beam_at_any_angle_and_nothing_enters_from_behind():
    """Rays across the beam, not across the plane z = const: at 89.9° the first surface's shadow is no
    wider than on axis (the plane's lattice would need ~600× the rays); from behind, no ray."""
    from dataclasses import replace

    from lensmount.trace.ghosts import launch
    from lensmount.physics.sources import CollimatedSource

    base = singlet_barrel(make_bsdf("absorber"), off_axis_deg=0.0, ghosts=True, coating="uncoated")
    sizes = {}
    for angle in (0.0, 60.0, 89.9, 120.0):
        scene = replace(base, source=CollimatedSource(angle, 90.0, base.source.disc))
        rays = launch(scene, 21)
        sizes[angle] = rays.positions
        assert np.all(rays.flux > 0) and np.allclose(np.linalg.norm(rays.directions, axis=1), 1.0)
    assert sizes[120.0] == 0 and sizes[89.9] <= 1.2 * sizes[0.0] and sizes[60.0] <= 1.2 * sizes[0.0]
