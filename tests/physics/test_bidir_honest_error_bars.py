"""The bidirectional estimate on the default radius schedule agrees
with a long forward reference within 3σ of (standard error + bias bound), and its reported 2σ
interval covers the reference in at least 18 of 20 seeds.

Case: the cooke-triplet example, every mount face and lens edge Lambertian
5 %, the sun at 25° (outside the ±20° field), a 36 × 24 mm detector at 300 × 200 pixels. The
sun's image misses the detector and lands on the housing bore just behind the detector plane:
before the gather stopped at that plane this read +12 % in total (+28 % housing, z = 2.5) and
its passes were heavy-tailed (spread 17 %, skew 1.2; now 6 %, skew 0).

Slow. Sizes here (to keep the file near 4 min on 2 cores): the reference 4 × 10⁶ forward
photons; the agreement run 16 passes × 10⁵; the coverage runs 20 seeds × 5 passes
× 2 × 10⁴ on the same scene at 150 × 100 pixels (the total flux is what is compared). Full-size figures are in the report of the change that added this file.
"""

import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from lensmount.analysis.passes import Accumulator
from lensmount.cad.pipeline import regenerate
from lensmount.mesh import TaggedMesh
from lensmount.design.folder import load_design
from lensmount.design.scene import scene_from_dict
from lensmount.integrators.bidirectional import bidirectional_pass
from lensmount.integrators.forward import forward_pass
from lensmount.integrators.photon_mapping.radius import radius_scale
from lensmount.scene.build import build_scene
from lensmount.trace.tracer import Tracer

pytestmark = pytest.mark.slow
EXAMPLE = Path(__file__).resolve().parents[2] / "src" / "lensmount" / "examples" / "cooke-triplet"

SCENE = {
    "source": {"type": "sun", "off_axis_deg": 25.0, "azimuth_deg": 90.0, "angular_diameter_deg": 0.53,
               "limb_darkening": False},
    "detector": {"width_mm": 36.0, "height_mm": 24.0, "pixels": [300, 200]},
    "effects": {"scatter": True, "ghosts": False, "direct": False},
    "coatings": {"default": "perfect-ar"},
    "finishes": {"lambert-5": {"model": "lambertian", "reflectance": 0.05}},
    "assign": {"*": "lambert-5"},
    "run": {"photons": 100_000, "passes": 16, "seed": 1},
}


@pytest.fixture(scope="module")
def cooke(tmp_path_factory):
    design = tmp_path_factory.mktemp("cooke")
    for name in ("lens.toml", "mount.toml"):
        shutil.copy(EXAMPLE / name, design / name)
    manifest = regenerate(design, design / "build")
    mesh = TaggedMesh.load(design / "build" / manifest.mesh)
    scene = build_scene(load_design(design).prescription, mesh, scene_from_dict(SCENE, base_dir=str(design)))
    return scene, Tracer(scene)


@pytest.fixture(scope="module")
def cooke_coarse(cooke):
    """The same scene on a 150 × 100 pixel detector: the total flux is the same quantity, and each
    coverage run's view map costs a quarter (20 seeds × 5 passes)."""
    scene, tracer = cooke
    n_x, n_y = (p // 2 for p in scene.detector.shape[::-1])
    coarse = replace(scene, detector=replace(scene.detector, nx=n_x, ny=n_y))
    return coarse, Tracer(coarse)


@pytest.fixture(scope="module")
def forward_reference(cooke):
    scene, tracer = cooke
    est = [forward_pass(scene, tracer, 400_000, 101, i) for i in range(10)]
    flux = np.array([e.flux for e in est])
    parts = np.array([e.part_flux for e in est])
    n = len(flux)
    return (flux.mean(), flux.std(ddof=1) / math.sqrt(n),
            dict(zip(est[0].part_names, zip(parts.mean(0), parts.std(0, ddof=1) / math.sqrt(n)))))


def _bidirectional(scene, tracer, seed, passes, photons):
    acc = None
    for i in range(passes):
        e = bidirectional_pass(scene, tracer, photons, seed, i, radius_scale(i))
        if acc is None:
            acc = Accumulator.empty(e.image.shape, e.part_names, e.pixel_area_mm2)
        acc.add(e, i)
    return acc


def _allowance(bound, ladder: np.ndarray) -> float:
    """What the agreement allows for the kernel bias: the run's bound, or, when the ladder's rule refuses
    one, the largest move of the mean estimate over the whole ladder r/2 … 2r (what the ladder can see).

    Why not assert a bound: on this scene the ladder is flat within its noise (64 passes of 4 seeds:
    every step within 1.2σ of zero and under 0.4 % of the flux), and the rule's model check is a test at
    a fixed level (`bias.SHAPE_P`), so on a bias-free ladder it refuses a fixed share of runs however many
    photons they have: 9 % of these passes' resamplings, 2 of seeds 1-4.
    A single-seed `bounded` would fail that share of runs with nothing wrong."""
    if bound.bounded:
        return bound.bound
    mean = ladder.mean(axis=0)
    return float(np.max(np.abs(mean - mean[0])))


def test_cooke_triplet_at_25_degrees_agrees_with_forward(cooke, forward_reference):
    scene, tracer = cooke
    f, f_se, f_parts = forward_reference
    acc = _bidirectional(scene, tracer, 1, 16, 100_000)
    total, per_part = acc.bias_bound()
    k = acc.part_names.index("housing")
    ladder = np.asarray(acc.pass_part_flux_ladder)  # (passes, rungs, parts); rung 0 is r itself
    bias = _allowance(total, ladder.sum(axis=2))
    part_bias = [_allowance(b, ladder[:, :, p]) for p, b in enumerate(per_part)]
    sigma = math.hypot(acc.flux_std_error + bias, f_se)
    assert abs(acc.flux - f) <= 3 * sigma, (acc.flux, acc.flux_std_error, bias, f, f_se)
    h, h_se = f_parts["housing"]
    h_sigma = math.hypot(acc.part_flux_std_error[k] + part_bias[k], h_se)
    assert abs(acc.part_flux[k] - h) <= 3 * h_sigma, (acc.part_flux[k], acc.part_flux_std_error[k], part_bias[k], h)
    print(f"cooke 25°: bidirectional {acc.flux:.5g} ± {acc.flux_std_error:.2g} (kernel bias allowed {bias:.2g}), "
          f"forward {f:.5g} ± {f_se:.2g}; housing {acc.part_flux[k]:.5g} ± {acc.part_flux_std_error[k]:.2g} "
          f"(bound {part_bias[k]:.2g}) vs {h:.5g} ± {h_se:.2g}; ladder: {total.reason or 'bounded'}")
    assert acc.flux_std_error + bias < 0.1 * acc.flux  # an error bar that says something


def test_reported_2_sigma_covers_the_forward_reference_in_18_of_20_seeds(cooke_coarse, forward_reference):
    scene, tracer = cooke_coarse
    f, f_se, _ = forward_reference
    inside = bounded = 0
    for seed in range(20):
        acc = _bidirectional(scene, tracer, 1000 + seed, 5, 20_000)
        bias = acc.bias_bound()[0]  # a run that cannot bound its bias claims no interval: honest
        inside += not bias.bounded or abs(acc.flux - f) <= 2 * acc.flux_std_error + bias.bound
        bounded += bias.bounded
    print(f"cooke 25°: forward {f:.5g} ± {f_se:.2g} inside the reported 2σ in {inside} of 20 seeds "
          f"({bounded} bounded their bias)")
    assert inside >= 18, inside
    # A run without a bound counts as inside (it claims no interval), so a rule that never bounded would pass
    # the line above: most runs must bound. The rule refuses ~10 % of runs of a bias-free ladder (its fixed-level
    # model check, `_allowance`); 18 of 20 bounded here. Below 14 is p < 0.3 % at that rate.
    assert bounded >= 14, bounded
