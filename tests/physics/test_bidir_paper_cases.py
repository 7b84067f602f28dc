"""The seed paper's cases 1–3 on the reference design (regenerated mount), and the
bidirectional estimator against the forward one on it. Slow: each test < 4 min.

Detector reduced to 60 × 60 pixels (the flux does not depend on the pixel count; the
images would only be noisier per pixel).
"""

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from lensmount.analysis.passes import Accumulator
from lensmount.cad.pipeline import regenerate
from lensmount.mesh import TaggedMesh
from lensmount.design.finishes import load_finishes
from lensmount.design.folder import load_design
from lensmount.design.scene import scene_from_dict
from lensmount.integrators.bidirectional import bidirectional_pass
from lensmount.integrators.forward import forward_pass
from lensmount.integrators.photon_mapping.radius import radius_scale
from lensmount.scene.build import build_scene
from lensmount.trace.tracer import Tracer

pytestmark = pytest.mark.slow
DESIGN = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"
# case 3 is the same lens and mount with another paint: a design of its own (its finishes.toml)
DESIGN_OF = {"case3-gaussian": DESIGN.parent / "double-gauss-360-gaussian-paint"}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("geometry")
    manifest = regenerate(DESIGN, out)
    return load_design(DESIGN).prescription, TaggedMesh.load(out / manifest.mesh)


def _scene(reference, case, pixels=60, off_axis_deg=None, azimuth_deg=None, **finish_override):
    lens, mesh = reference
    design = DESIGN_OF.get(case, DESIGN)
    path = design / "scenes" / f"{case}.toml"
    data = tomllib.loads(path.read_text()) | load_finishes(design).tables()
    data["detector"]["pixels"] = [pixels, pixels]
    if off_axis_deg is not None:
        data["source"]["off_axis_deg"] = off_axis_deg
    if azimuth_deg is not None:
        data["source"]["azimuth_deg"] = azimuth_deg
    for key, value in finish_override.items():
        data["finishes"][key] = value
    return build_scene(lens, mesh, scene_from_dict(data, base_dir=str(path.parent)))


def _accumulate(scene, method, passes, photons, seed=1, schedule=False, **kw) -> Accumulator:
    """The run's passes merged; schedule: the default radius schedule s_i."""
    tracer = Tracer(scene)
    if method == "bidirectional":
        est = [bidirectional_pass(scene, tracer, photons, seed, i, radius_scale(i) if schedule else 1.0, **kw)
               for i in range(passes)]
    else:
        est = [forward_pass(scene, tracer, photons, seed, i) for i in range(passes)]
    acc = Accumulator.empty(est[0].image.shape, est[0].part_names, est[0].pixel_area_mm2)
    for i, e in enumerate(est):
        acc.add(e, i)
    assert np.isfinite(acc.flux)
    return acc


def _run(scene, method, passes, photons, seed=1, schedule=False, **kw):
    """(mean, standard error, {part: mean}, bias bound); schedule: the default radius schedule s_i."""
    acc = _accumulate(scene, method, passes, photons, seed, schedule, **kw)
    bias = acc.bias_bound()[0]
    assert bias.bounded, bias.reason
    return acc.flux, acc.flux_std_error, dict(zip(acc.part_names, acc.part_flux)), bias.bound


@pytest.fixture(scope="module")
def bidirectional_case(reference):
    """case -> the 8-pass bidirectional run on the default radius schedule, traced once per module
    (the paper-case ordering and the forward agreement below read the same runs)."""
    runs = {}

    def run(case):
        if case not in runs:
            runs[case] = _run(_scene(reference, case), "bidirectional", 8, 50_000, schedule=True,
                              samples_per_pixel=SAMPLES_PER_PIXEL[case])
        return runs[case]
    return run


SAMPLES_PER_PIXEL = {"case2-lambertian": 16, "case3-gaussian": 1}


def test_case3_gaussian_is_brighter_than_case2_lambertian(bidirectional_case):
    m2, s2, _, _ = bidirectional_case("case2-lambertian")
    m3, s3, _, _ = bidirectional_case("case3-gaussian")
    assert m3 - m2 > math.hypot(s2, s3), (m2, s2, m3, s3)


def test_case1_light_comes_only_from_the_diaphragm_edge(reference):
    # 20 000 photons a pass, as the scene asks: most are aimed at the edge (integrators.photon_mapping.photon_target)
    m, s, parts, _ = _run(_scene(reference, "case1-diaphragm-edge"), "bidirectional", 6, 20_000, samples_per_pixel=16)
    # ~1.5 % with the photons aimed; uniform emission puts ~1 photon a pass on the edge here (~100 %)
    assert m > 0 and s < 0.05 * m, (m, s)
    lit = {name for name, f in parts.items() if f > 0}
    assert lit == {"diaphragm"}, parts


@pytest.mark.parametrize("case", ["case2-lambertian", "case3-gaussian"])
def test_bidirectional_agrees_with_forward_on_the_reference_design(reference, bidirectional_case, case):
    """The default radius schedule (not s = 1) agrees with forward within 3σ of (standard error + bias bound).

    Case 1 is not here: forward tracing sees no photon from the 50 µm edge in 8 × 10⁶ photons
    (bidirectional reads 3.3e-5 ± 0.5e-5 mm², bias bound 0.2e-5), so a forward reference for it
    is beyond a test's budget (docs/accuracy.md)."""
    bi = bidirectional_case(case)
    fw = _run(_scene(reference, case), "forward", 8, 200_000, seed=2)
    assert abs(bi[0] - fw[0]) <= 3 * math.hypot(bi[1] + bi[3], fw[1]), (bi[0], bi[1], bi[3], fw[:2])


def test_sun_image_on_the_housing_bore_at_the_edge_of_what_the_detector_sees(reference):
    """At 5.3° the sun's image (radius 360 mm · tan 5.3° = 33.4 mm) lands where the
    housing bore (R = 33.47 mm) meets the detector plane: the f/7 cone lights the bore both in
    front of the plane, which the detector sees at grazing angles, and behind it, which it
    cannot see. Case 2 finishes; default radius schedule against forward."""
    scene = _scene(reference, "case2-lambertian", off_axis_deg=5.3)
    bi = _run(scene, "bidirectional", 8, 50_000, schedule=True, samples_per_pixel=16)
    fw = _run(scene, "forward", 8, 200_000, seed=2)
    assert fw[2]["housing"] > 0.2 * fw[0], fw[2]  # the case is the one described: the housing matters
    assert abs(bi[0] - fw[0]) <= 3 * math.hypot(bi[1] + bi[3], fw[1]), (bi[0], bi[1], bi[3], fw[:2])


def test_relative_error_does_not_depend_on_the_edge_tis(reference):
    """The paper's claim on case 1 is about cost: 1 % and 10 % edge reflectance, the same photons
    with independent seeds, relative errors within the spread of an error estimate from 8 passes."""
    rel = []
    for seed, rho in ((1, 0.01), (2, 0.10)):
        scene = _scene(reference, "case1-diaphragm-edge",
                       **{"edge-lambert-10": {"model": "lambertian", "reflectance": rho}})
        m, s, _, _ = _run(scene, "bidirectional", 8, 20_000, seed=seed, samples_per_pixel=16)
        rel.append(s / m)
    assert 1 / 2.5 < rel[0] / rel[1] < 2.5, rel


def test_case_1_near_the_axis_reads_the_same_at_any_sun_azimuth(reference):
    """The mount is a body of revolution: case 1 with the sun 3° off axis must read the same from
    azimuth 90° and 45° (the 45° mesh differs only by its facets). At 3° the sunlit ring on the
    diaphragm edge is a third as bright as at 7°: a photon-aiming pilot of one round found too few
    edge hits there, fell back to uniform emission and read 0 at 45° (3.5e-9 at 0°, by luck)."""
    # The passes' own spread: at 3° the run's terms read a tail index near 1 (Hill, `analysis.passes.tail_index`),
    # where the run rightly quotes no error bar of its own; the symmetry is a question about the means.
    runs = [_accumulate(_scene(reference, "case1-diaphragm-edge", off_axis_deg=3.0, azimuth_deg=az), "bidirectional",
                        6, 20_000, schedule=True) for az in (90.0, 45.0)]
    (a, a_se), (b, b_se) = [(acc.flux, np.std(acc.pass_flux, ddof=1) / math.sqrt(acc.n)) for acc in runs]
    print(f"\ncase 1 at 3°: azimuth 90° {a:.4g} ± {a_se:.2g} mm², 45° {b:.4g} ± {b_se:.2g} mm²; terms' tail index "
          f"{runs[0].tail().index}, {runs[1].tail().index}")
    assert a > 0 and b > 0 and a_se < 0.15 * a and b_se < 0.15 * b
    assert abs(a - b) < 4 * math.hypot(a_se, b_se)
