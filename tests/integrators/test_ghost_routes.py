"""Deterministic ghost routes inside a pass: unbiased randomised lattices, path codes, no work without ghosts."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.analysis.ghosts import ghost_report  # noqa: E402
from lensmount.integrators.estimate import Film, film_channels  # noqa: E402
from lensmount.integrators.forward import Forward  # noqa: E402
from lensmount.integrators.ghost_routes import ghost_routes_pass, route_reflections  # noqa: E402
from lensmount.integrators.paths import ghost_code, ghost_route_code, route_of_code  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.trace.bsdf import make_bsdf  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


def test_a_route_code_names_its_surfaces_and_no_other_code_does():
    for route in [(2, 3), (6, 1), (3, 1, 3, 2), (63, 62)]:
        assert route_of_code(ghost_route_code(route)) == route
    assert len({ghost_route_code(r) for r in [(2, 1), (1, 2), (2, 1, 2, 1), (1, 2, 1, 2)]}) == 4
    for code in (*ghost_code(np.array([1, 2, 6])).tolist(), 0, 5):  # photons' reflection stretches, faces
        assert route_of_code(code) is None
    with pytest.raises(ValueError):
        ghost_route_code((64, 1))


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
    """Ghosts on, every surface perfect AR: no route is traced, the ghosts channel reads 0 and no ghost
    path is in the pass's paths."""
    import lensmount.integrators.ghost_routes as routes

    def fail(*args, **kwargs):
        raise AssertionError("ghost routes traced for a lens that cannot reflect")

    monkeypatch.setattr(routes, "trace_routes", fail)
    monkeypatch.setattr(routes, "launch", fail)
    scene = singlet_barrel(make_bsdf("absorber"), off_axis_deg=2.0, ghosts=True, coating="perfect-ar")
    assert route_reflections(scene, EstimatorSettings()) == ()
    estimate = Forward().run_pass(scene, Tracer(scene), 0, 2000, 1)
    assert estimate.part_flux[estimate.part_names.index("ghosts")] == 0.0
    assert all(route_of_code(c) is None for codes in estimate.paths.events.values() for c in codes)
