"""Bulk absorption in the tracer against the catalogue's own numbers (Beer-Lambert by hand).

A 5 mm N-SF6 window at 380 nm, where Schott's table gives an internal transmittance of
0.4804 for 10 mm: a ray crossing it at θ in air travels L = t / cos θ_t in the glass
(sin θ_t = sin θ / n) and keeps T10^(L / 10 mm). Perfect AR, so nothing else takes light.
"""

import math

import numpy as np
import pandas as pd
import pytest

from tests.trace.geometry import make_scene, window
from lensmount.optics.glass import _find_catalogue_glass
from lensmount.scene import primitives
from lensmount.physics.rays import RayBatch
from lensmount.trace.tracer import DETECTOR, FACE, Tracer

GLASS, WL_NM, T = "SCHOTT:N-SF6", 380.0, 5.0
SD = 20.0


def _catalogue():
    """(T10 at 380 nm, n at 380 nm) read straight from the Schott table (no interpolation)."""
    g = _find_catalogue_glass(GLASS)
    t10 = float(pd.to_numeric(pd.Series([g.glass_data()["internal transmission mm, 10"][WL_NM]])).iloc[0])
    return t10, float(g.calc_rindex(WL_NM))


def _slab(absorption: bool):
    p = window(T, GLASS, SD)
    p = type(p)(p.surfaces, p.aperture, (WL_NM / 1000.0,), (1.0,))
    mesh = primitives.lens_elements(p, [SD, SD], rings=4, segments=32)
    det = {"width_mm": 400, "height_mm": 400, "pixels": [1, 1]}
    return make_scene(p, mesh, detector=det, effects={"absorption": absorption, "direct": True})


def _rays_at(theta_deg, x0=0.0):
    th = np.radians(np.asarray(theta_deg, float))
    d = np.column_stack([np.sin(th), np.zeros_like(th), np.cos(th)])
    o = np.column_stack([np.full(len(th), x0), np.zeros(len(th)), np.zeros(len(th))]) - 1.0 * d  # 1 mm before
    return RayBatch.make(o, d)


def test_oblique_paths_through_a_slab_keep_the_catalogue_transmittance_to_the_power_l_over_10mm():
    t10, n = _catalogue()
    assert t10 == pytest.approx(0.4804, abs=1e-3)  # the table itself: a strongly absorbing case
    theta = np.array([0.0, 20.0, 40.0, 60.0, 75.0])
    ev = Tracer(_slab(True)).next_event(_rays_at(theta))
    assert np.all(ev.kind == DETECTOR)
    cos_t = np.sqrt(1.0 - (np.sin(np.radians(theta)) / n) ** 2)
    expected = t10 ** (T / cos_t / 10.0)
    np.testing.assert_allclose(ev.weight, expected, rtol=1e-9)
    assert expected[-1] < expected[0] - 0.03  # the oblique path really is longer (0.653 vs 0.693)
    off = Tracer(_slab(False)).next_event(_rays_at(theta))
    np.testing.assert_allclose(off.weight, 1.0, rtol=1e-12)  # the switch: lossless glass


def test_light_going_backward_through_the_slab_is_absorbed_alike():
    """Reciprocity: the bidirectional estimator's backward rays (detector to scene) use the same
    tracer; a ray crossing the window toward -z keeps the same fraction."""
    t10, n = _catalogue()
    theta = np.array([10.0, 50.0])
    th = np.radians(theta)
    d = np.column_stack([np.sin(th), np.zeros(2), -np.cos(th)])
    o = np.column_stack([np.zeros(2), np.zeros(2), np.full(2, T + 1.0)]) - 1e-9 * d
    ev = Tracer(_slab(True)).next_event(RayBatch.make(o, d))
    cos_t = np.sqrt(1.0 - (np.sin(th) / n) ** 2)
    np.testing.assert_allclose(ev.weight, t10 ** (T / cos_t / 10.0), rtol=1e-9)


def test_a_path_that_ends_on_the_lens_edge_from_inside_is_absorbed_along_its_length():
    """Stray light scattered by a lens's ground edge travels in the glass to it: the path from the
    front face to the edge (a FACE event on the lens part, reached from inside) is absorbed too."""
    t10, n = _catalogue()
    theta, x0 = 60.0, 19.0
    ev = Tracer(_slab(True)).next_event(_rays_at([theta], x0))
    assert ev.kind[0] == FACE and ev.position[0, 0] == pytest.approx(SD, abs=1e-6)
    sin_t = math.sin(math.radians(theta)) / n
    length = (ev.position[0, 0] - x0) / sin_t  # from the entry point (x0, 0, 0) along the refracted ray
    assert ev.position[0, 2] == pytest.approx(length * math.sqrt(1 - sin_t**2), abs=1e-6)
    assert ev.weight[0] == pytest.approx(t10 ** (length / 10.0), rel=1e-9)
