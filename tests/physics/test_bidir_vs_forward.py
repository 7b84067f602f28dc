"""Bidirectional against the forward estimator (the other engineer's unbiased reference).

Scene: a 100 mm f/4 singlet in a barrel whose inside scatters, the sun 8° off axis (out of
the ±5.7° field), so every detector photon has scattered in the barrel — small enough for
forward tracing to converge in seconds. Agreement is required within 3 combined standard
errors (batch means over passes).
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.integrators.bidirectional import bidirectional_pass  # noqa: E402
from lensmount.integrators.forward import forward_pass  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


def _flux(scene, tracer, method, passes, photons, seed=1, **kw):
    if method == "bidirectional":
        f = [bidirectional_pass(scene, tracer, photons, seed, i, 1.0, **kw).flux for i in range(passes)]
    else:
        f = [forward_pass(scene, tracer, photons, seed, i).flux for i in range(passes)]
    f = np.array(f)
    assert np.all(np.isfinite(f))
    return f.mean(), f.std(ddof=1) / math.sqrt(passes)


def _agree(a, b, k=3.0):
    (ma, sa), (mb, sb) = a, b
    return abs(ma - mb) <= k * math.hypot(sa, sb)


@pytest.mark.slow  # 5–25 s on 2 cores: runs in make test-all, out of the CI budget
def test_lambertian_barrel_agrees_with_forward():
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.1))
    tracer = Tracer(scene)
    bi = _flux(scene, tracer, "bidirectional", 8, 50_000, samples_per_pixel=128)
    fw = _flux(scene, tracer, "forward", 4, 100_000)
    assert bi[0] > 0 and fw[0] > 0
    assert bi[1] < 0.05 * bi[0]  # a meaningful comparison, not two huge error bars
    assert _agree(bi, fw), (bi, fw)


@pytest.mark.slow  # 5–25 s on 2 cores: runs in make test-all, out of the CI budget
def test_glossy_rule_on_a_5_degree_gaussian_barrel_agrees_with_forward():
    """5° lobe < the 15° threshold: its light is counted by the photons (last-vertex rule)."""
    scene = singlet_barrel(make_bsdf("gaussian", reflectance=0.1, half_width_deg=5.0))
    tracer = Tracer(scene)
    bi = _flux(scene, tracer, "bidirectional", 6, 100_000, samples_per_pixel=4)
    fw = _flux(scene, tracer, "forward", 6, 100_000, seed=2)
    assert _agree(bi, fw), (bi, fw)
    # And gathering the same lobe at hit points (threshold below 5°) is unbiased too, only noisier.
    ga = _flux(scene, tracer, "bidirectional", 6, 100_000, samples_per_pixel=256, glossy_threshold_deg=2.0)
    assert _agree(ga, fw), (ga, fw)


@pytest.mark.slow  # 5–25 s on 2 cores: runs in make test-all, out of the CI budget
def test_relative_error_does_not_grow_as_the_tis_falls():
    """The seed paper's claim is about cost: at a fixed number of photons the bidirectional
    estimate's relative error does not depend on the TIS (an analog forward tracer's grows as
    1/√TIS). Independent seeds at ρ = 0.3 and ρ = 10⁻⁴ (where every photon that scatters twice
    meets Russian roulette), 12 passes each: the relative errors agree within the spread of an
    error estimate from 12 passes (a factor 2.2 is 2.5 of its log-σ ≈ 0.31)."""
    rel = []
    for seed, rho in ((3, 0.3), (4, 1e-4)):
        scene = singlet_barrel(make_bsdf("lambertian", reflectance=rho))
        m, s = _flux(scene, Tracer(scene), "bidirectional", 12, 20_000, seed=seed, samples_per_pixel=32)
        assert m > 0
        rel.append(s / m)
    assert 1 / 2.2 < rel[1] / rel[0] < 2.2, rel


def test_direct_and_ghost_channels_match_forward():
    """Sun inside the field, uncoated glass, ghosts and direct on: the unscattered light is
    counted by the photons in the forward estimator's channels, the scatter by the gather."""
    scene = singlet_barrel(make_bsdf("lambertian", reflectance=0.1), off_axis_deg=3.0, ghosts=True, direct=True,
                           coating="uncoated")
    tracer = Tracer(scene)
    bi = [bidirectional_pass(scene, tracer, 50_000, 1, i, 1.0, samples_per_pixel=32) for i in range(6)]
    fw = [forward_pass(scene, tracer, 50_000, 2, i) for i in range(6)]
    assert bi[0].part_names == fw[0].part_names
    for channel in ("direct", "ghosts", "barrel"):
        k = fw[0].part_names.index(channel)
        b = np.array([e.part_flux[k] for e in bi])
        f = np.array([e.part_flux[k] for e in fw])
        assert f.mean() > 0, channel
        se = math.hypot(b.std(ddof=1), f.std(ddof=1)) / math.sqrt(6)
        assert abs(b.mean() - f.mean()) <= 3 * se + 1e-9 * f.mean(), (channel, b.mean(), f.mean(), se)


def test_black_paint_abg_is_gathered_outside_its_core_and_agrees_with_forward():
    """ABg A = 2e-3, B = 1e-3, g = 2 has a 1.8° half width but most of its
    albedo in the wings. It used to be routed to the photons by its half width alone; now its
    wings are gathered at hit points and only the core (within sin 15° of the mirror direction)
    is left to the photons. The split must not lose or double count: bidirectional = forward."""
    from lensmount.integrators.bidirectional import gather_cores

    abg = make_bsdf("abg", A=2e-3, B=1e-3, g=2)
    scene = singlet_barrel(abg)
    core = gather_cores(scene.bsdf_of_tag)
    barrel = [k for k, t in enumerate(scene.mesh.tag_table) if t.part == "barrel"]
    assert np.all(core[barrel] == pytest.approx(math.sin(math.radians(15.0))))
    tracer = Tracer(scene)
    bi = _flux(scene, tracer, "bidirectional", 6, 50_000, samples_per_pixel=16)
    fw = _flux(scene, tracer, "forward", 6, 100_000, seed=2)
    assert bi[0] > 0 and bi[1] < 0.1 * bi[0]
    assert _agree(bi, fw), (bi, fw)


@pytest.mark.slow  # ~60 s on 2 cores
def test_a_detector_immersed_in_water_agrees_with_forward():
    """The image formed in water (n 1.333): the photons deposit flux, the same in any medium, while the
    backward samples estimate E = ∫ L cos θ dω over the hemisphere in the water, where the barrel's
    radiance seen through the lens is n² L (L / n² is what crosses an interface). Without the detector's
    n² (integrators/photon_mapping/media.py) bidirectional reads 1/1.78 of forward."""
    from lens_scenes import immersed_singlet  # noqa: E402

    scene = immersed_singlet(make_bsdf("lambertian", reflectance=0.1))
    assert scene.detector.medium_index == (1.333,)
    tracer = Tracer(scene)
    bi = _flux(scene, tracer, "bidirectional", 8, 50_000, samples_per_pixel=128)
    fw = _flux(scene, tracer, "forward", 8, 200_000, seed=2)
    assert bi[0] > 0 and fw[0] > 0 and fw[1] < 0.05 * fw[0] and bi[1] < 0.05 * bi[0]
    assert _agree(bi, fw), (bi, fw)
