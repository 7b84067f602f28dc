"""Review: wavelength bookkeeping with several wavelengths. Backward samples pick one of W wavelengths
uniformly and carry τ = w·W; photons pick theirs by the source's spectral weights and carry the full
Φ = A_S/N. With unequal source weights p_k and a detector response s_k the bidirectional estimate must
match forward tracing, and forward must scale the achromatic barrel scatter by Σ p_k s_k."""

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.integrators.bidirectional import bidirectional_pass  # noqa: E402
from lensmount.integrators.forward import forward_pass  # noqa: E402
from lensmount.optics.prescription import Aperture, Prescription, Surface  # noqa: E402
from lensmount.scene.build import optical_surfaces, solid_absorption_of_tag, solid_index_of_tag  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402
from lensmount.physics.detector import Detector  # noqa: E402
from lensmount.physics.interfaces import parse_coating  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402

WL = (0.4861327, 0.5875618, 0.6562725)
P = np.array([1.0, 2.0, 1.0])  # source spectral weights
S = (0.5, 1.0, 0.8)  # detector response


def _three_wavelengths(base):
    h = 12.5
    lens = Prescription((Surface(51.68, 6.0, "N-BK7", is_stop=True, clear_semi_diameter=h, mechanical_semi_diameter=h),
                         Surface(math.inf, 96.0, "AIR", clear_semi_diameter=h, mechanical_semi_diameter=h)),
                        Aperture("epd", 2 * h), WL, tuple(P), 1, (0.0,), "singlet")
    coat = parse_coating("perfect-ar")
    d = base.detector
    return replace(base, optical=optical_surfaces(lens, np.array(WL), lambda i, c: coat), wavelengths_um=np.array(WL),
                   solid_index_of_tag=solid_index_of_tag(lens, base.mesh, np.array(WL)),
                   solid_absorption_of_tag=solid_absorption_of_tag(lens, base.mesh, np.array(WL)),
                   source=replace(base.source, wavelength_weights=tuple(P)),
                   detector=Detector(d.width, d.height, d.nx, d.ny, d.z, S))


def _mean_se(values):
    v = np.array(values)
    assert np.all(np.isfinite(v))
    return v.mean(), v.std(ddof=1) / math.sqrt(len(v))


@pytest.mark.slow  # 5–25 s on 2 cores: runs in make test-all, out of the CI budget
def test_three_wavelengths_with_source_weights_and_detector_response():
    base = singlet_barrel(make_bsdf("lambertian", reflectance=0.1))
    scene = _three_wavelengths(base)
    tracer = Tracer(scene)
    bi = _mean_se([bidirectional_pass(scene, tracer, 40_000, 1, i, 1.0, samples_per_pixel=64).flux for i in range(6)])
    fw = _mean_se([forward_pass(scene, tracer, 100_000, 2, i).flux for i in range(6)])
    assert abs(bi[0] - fw[0]) <= 3 * math.hypot(bi[1], fw[1]), (bi, fw)
    assert bi[1] < 0.08 * bi[0]  # a meaningful comparison
    # The W factor cannot hide in both: forward against the single-wavelength scene × Σ p_k s_k.
    tr1 = Tracer(base)
    one = _mean_se([forward_pass(base, tr1, 100_000, 3, i).flux for i in range(6)])
    expected = float(P / P.sum() @ np.array(S)) * one[0]
    tol = 3 * math.hypot(fw[1], float(P / P.sum() @ np.array(S)) * one[1]) + 0.01 * expected  # 1 %: dispersion
    assert abs(fw[0] - expected) <= tol, (fw, one, expected)
