"""The shared photon walk: results keyed by photon, not by how the run is split; the energy ledger.

Scenes are the numpy-built lens scenes of `lens_scenes.py` (real tracer, no CAD), so these run
in seconds; `tests/physics/test_energy_ledger_examples.py` (slow) checks the example designs.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lens_scenes import double_gauss_case, singlet_barrel  # noqa: E402
from planar import Collimated, Detector, Face, Lambert, PlanarScene, PlanarTracer  # noqa: E402

from lensmount.analysis.passes import Accumulator  # noqa: E402
from lensmount.integrators.estimate import ledger_residual  # noqa: E402
from lensmount.integrators.forward import Forward  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.integrators.walk import NonFiniteError  # noqa: E402
from lensmount.integrators.registry import integrator  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


def _forward_run(scene, tracer, passes, per_pass, *, batch=200_000, seed=3):
    """Photons only: the ghosts channel from the stochastic branch (deterministic routes off)."""
    acc = Accumulator.empty(scene.detector.shape, Forward().channels(scene), scene.detector.pixel_area)
    photons_only = EstimatorSettings(ghost_routes=False)
    for i in range(passes):
        acc.add(Forward(photons_only, batch=batch).run_pass(scene, tracer, i, per_pass, seed), i)
    return acc


def test_forward_is_the_same_however_the_photons_are_split():
    """4 passes × N, 2 passes × 2N and 1 pass × 4N in batches of N/3 trace the same photons with the
    same numbers (ghost branches included): same images, per-part and total flux, to rounding."""
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.3), off_axis_deg=3.0, ghosts=True, direct=True,
                           coating="R=0.3")  # strong ghosts: the Fresnel branch is exercised
    tracer = Tracer(scene)
    a = _forward_run(scene, tracer, 4, 3000)
    b = _forward_run(scene, tracer, 2, 6000)
    c = _forward_run(scene, tracer, 1, 12000, batch=1000)
    flux = a.part_flux
    assert np.all(flux[[a.part_names.index(n) for n in ("barrel", "direct", "ghosts")]] > 0)  # every channel lit
    for other in (b, c):
        np.testing.assert_allclose(other.mean_image, a.mean_image, rtol=1e-12, atol=1e-14 * a.mean_image.max())
        np.testing.assert_allclose(other.mean_parts, a.mean_parts, rtol=1e-12, atol=1e-14 * a.mean_image.max())
        np.testing.assert_allclose(other.part_flux, flux, rtol=1e-12)
        assert other.flux == pytest.approx(a.flux, rel=1e-12)
    d = _forward_run(scene, tracer, 2, 6000, seed=4)  # the check has teeth: another seed is another answer
    assert abs(d.part_flux[d.part_names.index("ghosts")] / flux[a.part_names.index("ghosts")] - 1) > 1e-6


def _scenes():
    return {
        "case1": lambda: double_gauss_case(1, pixels=(12, 12)),
        "case2-ghosts": lambda: double_gauss_case(2, pixels=(12, 12), ghosts=True),
        "case3": lambda: double_gauss_case(3, pixels=(12, 12)),
        "singlet-uncoated": lambda: singlet_barrel(make_bsdf("lambertian", reflectance=0.8), coating="uncoated",
                                                   direct=True),
    }


@pytest.mark.parametrize("method", ["forward", "bidirectional"])
@pytest.mark.parametrize("name", list(_scenes()))
def test_energy_ledger_balances(method, name):
    scene = _scenes()[name]()
    est = integrator(method, EstimatorSettings(samples_per_pixel=1)).run_pass(scene, Tracer(scene), 0, 4000, 1)
    ledger = est.ledger
    assert ledger["source"] > 0 and abs(ledger_residual(ledger)) < 1e-9, ledger
    assert all(math.isfinite(v) for v in ledger.values())
    if method == "forward":  # the film holds exactly what the ledger says reached it
        for name_, flux in zip(est.part_names, est.part_flux):
            assert ledger.get(f"detector/{name_}", 0.0) == pytest.approx(flux, rel=1e-9, abs=1e-12)
        assert not any(k.startswith("detector_gathered/") for k in ledger)


def test_ledger_names_the_fresnel_loss_of_uncoated_glass():
    """On axis, every photon inside the clear aperture (area π h²) crosses both faces of the uncoated
    singlet: with ghosts off the optics keep 1 − (1 − R)² of it (R = 4.2 % for N-BK7), which
    the ledger reports as `glass`; with a perfect AR coating (and the bulk absorption off) it is zero."""
    n = 1.5168
    r0 = ((n - 1) / (n + 1)) ** 2
    h = 12.5
    uncoated = singlet_barrel(make_bsdf("absorber"), off_axis_deg=0.0, coating="uncoated", absorption=False)
    est = Forward().run_pass(uncoated, Tracer(uncoated), 0, 40_000, 2)
    expected = math.pi * h * h * (1 - (1 - r0) ** 2)
    assert est.ledger["glass"] == pytest.approx(expected, rel=0.03)  # photon noise ~1 %
    ar = singlet_barrel(make_bsdf("absorber"), off_axis_deg=0.0, absorption=False)
    assert abs(Forward().run_pass(ar, Tracer(ar), 0, 5000, 2).ledger["glass"]) < 1e-12 * est.ledger["source"]


def _plate(bsdf):
    th = math.radians(30)
    d = (math.sin(th), 0, -math.cos(th))
    return PlanarScene([Face((0, 0, 0), (0, 0, 1), (1, 0, 0), (20.0, 0), "plate", disc=True)], [bsdf],
                       Detector(2.0, 2.0, 4, 4, 20.0), Collimated(d, (-300 * d[0], 0, 300 * -d[2]), 25.0))


class _NaNFinish(Lambert):
    def sample(self, wi, n, u):
        wo, w, pdf = super().sample(wi, n, u)
        return wo, np.where(u[:, 0] < 0.01, np.nan, w), pdf


@pytest.mark.parametrize("method", ["forward", "bidirectional"])
def test_a_non_finite_bsdf_weight_is_an_error_naming_the_face(method):
    scene = _plate(_NaNFinish(0.5))
    with pytest.raises(NonFiniteError, match="part 'plate'"):
        integrator(method, EstimatorSettings(samples_per_pixel=4)).run_pass(scene, PlanarTracer(scene), 0, 2000, 1)


def test_settings_out_of_range_are_input_errors():
    from lensmount.errors import InputError

    with pytest.raises(InputError, match="roulette_level"):
        EstimatorSettings(roulette_level=0.0)
    with pytest.raises(InputError, match="unknown estimator setting 'radius'"):
        EstimatorSettings.from_dict({"radius": 1.0})
    assert EstimatorSettings.from_dict(EstimatorSettings(neighbours=4).as_dict()) == EstimatorSettings(neighbours=4)


def test_a_lens_without_an_entrance_pupil_is_an_input_error_not_a_zero_stray_fraction():
    from lensmount.errors import InputError
    from lensmount.optics.prescription import Aperture, Prescription, Surface
    from lensmount.scene.build import entrance_pupil_area

    window = Prescription((Surface(math.inf, 5.0, "N-BK7", is_stop=True, clear_semi_diameter=10,
                                   mechanical_semi_diameter=10),
                           Surface(math.inf, 50.0, "AIR", clear_semi_diameter=10, mechanical_semi_diameter=10)),
                          Aperture("fno", 4.0), (0.5875618,), (1.0,), 0, (0.0,), "window")
    with pytest.raises(InputError, match="entrance pupil"):
        entrance_pupil_area(window)
    singlet = Prescription((Surface(51.68, 6.0, "N-BK7", is_stop=True, clear_semi_diameter=12.5,
                                    mechanical_semi_diameter=12.5),
                            Surface(math.inf, 96.0, "AIR", clear_semi_diameter=12.5, mechanical_semi_diameter=12.5)),
                           Aperture("epd", 25.0), (0.5875618,), (1.0,), 0, (0.0,), "singlet")
    assert entrance_pupil_area(singlet) == pytest.approx(math.pi * 12.5**2, rel=1e-9)


def test_backward_samples_are_keyed_by_pixel_and_sample():
    """Sample j of pixel p draws the same numbers whatever the samples per pixel: with 4 samples the
    hit points of samples 0 and 1 are those of a 2-sample view map (at half the weight)."""
    from lensmount.integrators.photon_mapping.radius import radius_caps
    from lensmount.integrators.photon_mapping.view_map import build_view_map, view_map_streams

    scene = PlanarScene([Face((0, 0, 0), (0, 0, 1), (1, 0, 0), (1e4, 0), "plate", disc=True)], [Lambert(0.5)],
                        Detector(2.0, 2.0, 4, 4, 20.0), Collimated((0, 0, 1), (0, 0, -300), 25.0))
    det, tracer, m = scene.detector, PlanarTracer(scene), scene.mesh
    caps = radius_caps(m.vertices, m.triangles, m.tags, len(m.tag_table))
    maps = {}
    for spp in (2, 4):
        stats = {}
        maps[spp] = build_view_map(scene, tracer, det, view_map_streams(7, 3, det, spp), broad=np.array([True]),
                                   half_widths=caps, radius_scale=1.0, samples_per_pixel=spp, stats=stats)
        n = det.nx * det.ny * spp  # no optics: every sample sees the plate straight
        assert stats == {"view_map_samples": n, "view_map_lost_samples": 0, "view_map_direct_hit_points": n}
    two, four = maps[2], maps[4]
    assert len(two) == det.nx * det.ny * 2 and len(four) == 2 * len(two)  # every sample sees the wide plate
    first = np.isin(np.arange(len(four)) % 4, (0, 1))
    np.testing.assert_array_equal(four.position[first], two.position)
    np.testing.assert_allclose(four.weight[first], 0.5 * two.weight, rtol=1e-12)
    other = build_view_map(scene, tracer, det, view_map_streams(7, 4, det, 2), broad=np.array([True]),
                           half_widths=caps, radius_scale=1.0, samples_per_pixel=2)
    assert not np.array_equal(other.position, two.position)  # another pass, other numbers


class _NaNEval(Lambert):
    def eval(self, wi, wo, n):
        f = super().eval(wi, wo, n)
        return np.where(np.arange(len(f)) % 50 == 0, np.nan, f)


@pytest.mark.parametrize("connect, what", [(False, "gather"), (True, "connection")])
def test_a_non_finite_gather_value_is_an_error_naming_the_face(connect, what):
    """The plate is seen straight from the detector: its light is the gather's, or the connections' (`connect`)."""
    scene = _plate(_NaNEval(0.5))
    settings = EstimatorSettings(samples_per_pixel=4, connect_direct_view=connect)
    with pytest.raises(FloatingPointError, match=f"non-finite {what} value on face tag 0"):
        integrator("bidirectional", settings).run_pass(scene, PlanarTracer(scene), 0, 2000, 1)
