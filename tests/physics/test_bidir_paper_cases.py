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

from lensmount.cad import regenerate
from lensmount.cad.mesh import TaggedMesh
from lensmount.design.folder import load_design
from lensmount.design.scene import scene_from_dict
from lensmount.integrators.bidirectional import bidirectional_pass
from lensmount.integrators.forward import forward_pass
from lensmount.scene.build import build_scene
from lensmount.trace.tracer import Tracer

pytestmark = pytest.mark.slow
DESIGN = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("geometry")
    manifest = regenerate(DESIGN, out)
    return load_design(DESIGN).prescription, TaggedMesh.load(out / manifest.mesh)


def _scene(reference, case, pixels=60, **finish_override):
    lens, mesh = reference
    path = DESIGN / "scenes" / f"{case}.toml"
    data = tomllib.loads(path.read_text())
    data["detector"]["pixels"] = [pixels, pixels]
    for key, value in finish_override.items():
        data["finishes"][key] = value
    return build_scene(lens, mesh, scene_from_dict(data, base_dir=str(path.parent)))


def _run(scene, method, passes, photons, seed=1, **kw):
    tracer = Tracer(scene)
    if method == "bidirectional":
        est = [bidirectional_pass(scene, tracer, photons, seed, i, 1.0, **kw) for i in range(passes)]
    else:
        est = [forward_pass(scene, tracer, photons, seed, i) for i in range(passes)]
    flux = np.array([e.flux for e in est])
    assert np.all(np.isfinite(flux))
    parts = np.mean([e.part_flux for e in est], axis=0)
    return flux.mean(), flux.std(ddof=1) / math.sqrt(passes), dict(zip(est[0].part_names, parts))


def test_case3_gaussian_is_brighter_than_case2_lambertian(reference):
    m2, s2, _ = _run(_scene(reference, "case2-lambertian"), "bidirectional", 6, 200_000, samples_per_pixel=16)
    m3, s3, _ = _run(_scene(reference, "case3-gaussian"), "bidirectional", 6, 200_000, samples_per_pixel=1)
    assert m3 - m2 > math.hypot(s2, s3), (m2, s2, m3, s3)


def test_case1_light_comes_only_from_the_diaphragm_edge(reference):
    m, s, parts = _run(_scene(reference, "case1-diaphragm-edge"), "bidirectional", 6, 200_000, samples_per_pixel=16)
    assert m > 0 and s < 0.3 * m
    lit = {name for name, f in parts.items() if f > 0}
    assert lit == {"diaphragm"}, parts


@pytest.mark.parametrize("case,spp", [("case2-lambertian", 16), ("case3-gaussian", 1)])
def test_bidirectional_agrees_with_forward_on_the_reference_design(reference, case, spp):
    scene = _scene(reference, case)
    bi = _run(scene, "bidirectional", 8, 200_000, samples_per_pixel=spp)
    fw = _run(scene, "forward", 8, 200_000, seed=2)
    assert abs(bi[0] - fw[0]) <= 3 * math.hypot(bi[1], fw[1]), (bi[:2], fw[:2])


def test_relative_error_does_not_depend_on_the_edge_tis(reference):
    """The paper's claim on case 1: 1 % and 10 % edge reflectance, same photons, same relative error."""
    rel = []
    for rho in (0.01, 0.10):
        scene = _scene(reference, "case1-diaphragm-edge",
                       **{"edge-lambert-10": {"model": "lambertian", "reflectance": rho}})
        m, s, _ = _run(scene, "bidirectional", 8, 200_000, samples_per_pixel=16)
        rel.append(s / m)
    assert rel[0] == pytest.approx(rel[1], rel=0.35), rel
