"""Review: the on-face gather area A(y) against an independent closed form, where the straight-boundary
model is claimed exact: the interior of a thin flat strip and the 50 µm cylindrical diaphragm edge
(its two rims are straight lines in the tangent plane). The band integral
∫ 2 √(r² − y²) dy = [y √(r² − y²) + r² asin(y/r)] is written here, not taken from radius.py."""

import math

import numpy as np
import pytest

from lensmount.integrators.photon_mapping.radius import FaceBoundaries


def _band_in_disc(y_lo, y_hi, r):
    """Area of {|p| ≤ r, y_lo ≤ p_y ≤ y_hi} for a disc centred at the origin."""
    F = lambda y: y * math.sqrt(r * r - y * y) + r * r * math.asin(y / r)  # noqa: E731
    lo, hi = max(y_lo, -r), min(y_hi, r)
    return F(hi) - F(lo) if hi > lo else 0.0


def _strip_mesh(length, width, n):
    x = np.linspace(-length / 2, length / 2, n + 1)
    v = np.vstack([np.column_stack([x, np.full(n + 1, y), np.zeros(n + 1)]) for y in (-width / 2, width / 2)])
    i = np.arange(n)
    t = np.vstack([np.column_stack([i, i + 1, n + 2 + i]), np.column_stack([i, n + 2 + i, n + 1 + i])])
    return v, t


@pytest.mark.parametrize("r", [0.01, 0.1, 2.0])
def test_strip_interior_area_is_the_band_inside_the_disc(r):
    w = 0.05
    v, t = _strip_mesh(40.0, w, 200)
    fb = FaceBoundaries(v, t, np.zeros(len(t), np.int32), 1)
    ys = np.array([0.0, 0.01, -0.02, 0.0249])
    pos = np.column_stack([np.linspace(-5, 5, len(ys)), ys, np.zeros(len(ys))])
    area = fb.inside_area(pos, np.tile([0.0, 0.0, 1.0], (len(ys), 1)), np.zeros(len(ys), np.int32), np.full(len(ys), r))
    for a, y in zip(area, ys):
        assert a == pytest.approx(_band_in_disc(-w / 2 - y, w / 2 - y, r), rel=1e-9), (r, y)


def test_cylindrical_diaphragm_edge_area_is_exact_in_its_tangent_plane():
    """A 50 µm wide cylinder of radius 25.715 mm (the reference stop), r = 2 mm ≫ w: A = the band ≈ 2 r w."""
    R, w, seg = 25.715, 0.05, 2048
    phi = np.linspace(0, 2 * np.pi, seg, endpoint=False)
    v = np.vstack([np.column_stack([R * np.cos(phi), R * np.sin(phi), np.full(seg, z)]) for z in (-w / 2, w / 2)])
    i = np.arange(seg)
    j = (i + 1) % seg
    t = np.vstack([np.column_stack([i, j, seg + j]), np.column_stack([i, seg + j, seg + i])])
    fb = FaceBoundaries(v, t, np.zeros(len(t), np.int32), 1)
    zs = np.array([0.0, 0.02, -0.015])
    ang = np.array([0.1, 1.3, 4.0])
    pos = np.column_stack([R * np.cos(ang), R * np.sin(ang), zs])
    nrm = -np.column_stack([np.cos(ang), np.sin(ang), np.zeros(3)])  # inward, toward the axis
    r = 2.0
    area = fb.inside_area(pos, nrm, np.zeros(3, np.int32), np.full(3, r))
    for a, z in zip(area, zs):
        assert a == pytest.approx(_band_in_disc(-w / 2 - z, w / 2 - z, r), rel=1e-6)
        assert a == pytest.approx(2 * r * w, rel=0.01)
