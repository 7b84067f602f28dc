"""Radius schedule against its recurrence; face half widths against geometry."""

import math

import numpy as np
import pytest

from lensmount.integrators.photon_mapping.radius import (
    FaceBoundaries, boundary_segments, face_half_widths, initial_radii, radius_caps, radius_scale)


def test_schedule_matches_recurrence_for_10000_passes():
    alpha = 0.7
    s2 = 1.0
    for i in range(1, 10001):
        assert radius_scale(i - 1, alpha) == pytest.approx(math.sqrt(s2), rel=1e-9)
        s2 *= (i + alpha) / (i + 1)
    s = radius_scale(9999, alpha)
    assert 0 < s < 0.3 and math.isfinite(s)
    # s_i² ~ Γ(2)/Γ(1+α) · i^(α−1) for large i
    assert s**2 == pytest.approx(10000 ** (alpha - 1) / math.gamma(1 + alpha), rel=1e-3)


def test_alpha_outside_range_is_refused():
    with pytest.raises(ValueError):
        radius_scale(3, 1.0)


def _strip(width, length, n=20):
    """A flat strip width × length as 2n triangles, tag 0, and a square plate beside it, tag 1."""
    xs = np.linspace(0, length, n + 1)
    v = np.concatenate([np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], 1),
                        np.stack([xs, np.full_like(xs, width), np.zeros_like(xs)], 1)])
    tri = []
    for i in range(n):
        tri += [[i, i + 1, n + 1 + i], [i + 1, n + 2 + i, n + 1 + i]]
    plate_v = np.array([[0, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]], float) + [0, width, 0]
    tri += [[len(v), len(v) + 1, len(v) + 2], [len(v), len(v) + 2, len(v) + 3]]
    return np.concatenate([v, plate_v]), np.array(tri), np.array([0] * 2 * n + [1, 1])


def test_face_half_width_of_a_strip_and_a_square():
    v, tri, tags = _strip(0.05, 100.0)
    hw = face_half_widths(v, tri, tags, 3)
    assert hw[0] == pytest.approx(0.05 * 100 / (2 * 100.05), rel=1e-9)  # ≈ w/2
    assert hw[1] == pytest.approx(0.25)  # square of side 1: area 1 / perimeter 4
    assert hw[2] == np.inf


def test_initial_radii_never_exceed_the_face():
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.random(50) * 100, rng.random(50) * 0.05, np.zeros(50)])
    r = initial_radii(p, np.zeros(50, int), np.array([0.05]))
    assert np.all(r <= 0.05) and np.all(r > 0)


def test_strips_may_gather_along_their_length_compact_faces_not():
    v, tri, tags = _strip(0.05, 100.0)
    caps = radius_caps(v, tri, tags, 2, cap_mm=5.0)
    assert caps[0] == 5.0  # the 50 µm strip: along its length
    assert caps[1] == pytest.approx(0.5)  # the unit square: its full width 2 · (1/4)


def _disc_on_strip_area(y0, r, w, n=2001):
    """Area of disc (centre at height y0 in a strip |y| ≤ w/2) on the strip, by quadrature."""
    ys = np.linspace(max(y0 - r, -w / 2), min(y0 + r, w / 2), n)
    chord = 2 * np.sqrt(np.maximum(r * r - (ys - y0) ** 2, 0))
    return np.trapezoid(chord, ys)


@pytest.mark.parametrize("r", [0.01, 0.025, 0.05, 2.0])
def test_on_face_area_of_gather_discs_on_a_50um_strip(r):
    v, tri, tags = _strip(0.05, 100.0, n=200)
    fb = FaceBoundaries(v, tri, tags, 2)
    y0 = np.array([0.025, 0.01, 0.002, 0.045])
    pos = np.column_stack([np.full(4, 50.3), y0, np.zeros(4)])
    area = fb.inside_area(pos, np.tile([0, 0, 1.0], (4, 1)), np.zeros(4, int), np.full(4, r))
    expected = [_disc_on_strip_area(y - 0.025, r, 0.05) for y in y0]
    np.testing.assert_allclose(area, expected, rtol=1e-3)


def test_boundaries_of_a_triangle_soup_are_welded():
    v, tri, tags = _strip(0.05, 10.0, n=4)
    soup_v = v[tri.ravel()]
    soup_t = np.arange(len(soup_v)).reshape(-1, 3)
    a, b, t = boundary_segments(soup_v, soup_t, tags)
    a2, b2, t2 = boundary_segments(v, tri, tags)
    assert len(a) == len(a2) == 10 + 4


def test_a_hit_point_just_outside_a_strip_keeps_the_strip_area():
    v, tri, tags = _strip(0.05, 100.0, n=200)
    fb = FaceBoundaries(v, tri, tags, 2)
    r = 2.0
    pos = np.array([[50.3, -0.006, 0.0]])  # 6 µm beyond the y = 0 edge
    area = fb.inside_area(pos, np.array([[0, 0, 1.0]]), np.zeros(1, int), np.array([r]))
    ys = np.linspace(0.0, 0.05, 2001)
    expected = np.trapezoid(2 * np.sqrt(r * r - (ys + 0.006) ** 2), ys)
    assert area[0] == pytest.approx(expected, rel=1e-3)


def _annulus(r_in, r_out, seg):
    """Flat annulus in z = 0 with `seg` segments per rim (as the CAD tessellation makes them)."""
    phi = np.linspace(0.0, 2 * np.pi, seg, endpoint=False)
    inner = np.column_stack([r_in * np.cos(phi), r_in * np.sin(phi), np.zeros(seg)])
    outer = np.column_stack([r_out * np.cos(phi), r_out * np.sin(phi), np.zeros(seg)])
    i = np.arange(seg)
    j = (i + 1) % seg
    tri = np.concatenate([np.column_stack([i, seg + i, seg + j]), np.column_stack([i, seg + j, j])])
    return np.vstack([inner, outer]), tri


def test_a_disc_wholly_on_a_coarse_annulus_keeps_its_whole_area():
    """Regression (review): with 240 segments per rim the 24 nearest segments all lie on one
    rim; the centre must still be recognised as on the face, so A = π r² (it was π r²/4)."""
    v, tri = _annulus(20.31, 28.98, 240)
    fb = FaceBoundaries(v, tri, np.zeros(len(tri), np.int32), 1)
    rho = np.array([21.0, 21.865, 23.0, 24.6, 26.5, 28.0])
    pos = np.column_stack([rho, np.zeros(len(rho)), np.zeros(len(rho))])
    area = fb.inside_area(pos, np.tile([0, 0, 1.0], (len(rho), 1)), np.zeros(len(rho), np.int32), np.full(len(rho), 0.5))
    np.testing.assert_allclose(area, np.pi * 0.25, rtol=1e-9)


def _inside_area_numpy(fb, position, normal, tag, radius, detector_z):
    """The on-face area as the (H, k, 3) numpy formulas computed it before the nearest boundaries
    (radius._nearest_boundaries) and the caps (radius._disc_areas) were compiled, with the candidates
    from scipy's KD-tree before the grid (`neighbours.k_nearest`) found them: the reference the
    compiled search must equal to rounding."""
    from scipy.spatial import cKDTree

    area = np.pi * radius**2
    for t in np.unique(tag):
        idx = np.flatnonzero(tag == t)
        a, b, inward, middle = fb.by_tag[int(t)]
        k = min(fb.k, len(a))
        cand = cKDTree(middle).query(position[idx], k=k)[1].reshape(len(idx), k)
        p = position[idx][:, None, :]
        sa, ab = a[cand], b[cand] - a[cand]
        s = np.clip(np.einsum("hkj,hkj->hk", p - sa, ab) / np.maximum(np.einsum("hkj,hkj->hk", ab, ab), 1e-300), 0, 1)
        v = sa + s[..., None] * ab - p
        nrm = normal[idx][:, None, :]
        v = v - np.einsum("hkj,hkj->hk", v, nrm)[..., None] * nrm
        d = np.linalg.norm(v, axis=2)
        rows, near = np.arange(len(idx)), np.argmin(d, axis=1)
        d1 = d[rows, near]
        u1 = v[rows, near] / np.maximum(d1, 1e-300)[:, None]
        on_face = np.einsum("hj,hj->h", -v[rows, near], inward[cand[rows, near]]) >= 0.0
        beyond = np.einsum("hkj,hj->hk", v, u1) < 0
        d2 = np.where(beyond, d, np.inf).min(axis=1)
        near_cut, far_cut = d1, d2
        if detector_z is not None:
            near_cut, far_cut = _cut_by_plane(position[idx], normal[idx], u1, d1, d2, detector_z)
        r = radius[idx]
        d2r = np.where(np.isfinite(far_cut), far_cut, r)
        inside = np.pi * r * r - _cap(near_cut, r) - _cap(d2r, r)
        far = np.where(~beyond & (d > d1[:, None] + fb.half_width.get(int(t), np.inf)), d, np.inf).min(axis=1)
        band = _cap(d1, r) - _cap(np.where(np.isfinite(far), far, r), r)
        inside = np.where(on_face, inside, band)
        width = np.where(on_face, near_cut + d2r, np.where(np.isfinite(far), far - d1, r))
        floor = 0.5 * np.minimum(0.5 * np.pi * r * r, r * width)
        area[idx] = np.maximum(inside, np.maximum(floor, 1e-12 * np.pi * r * r))
    return area


def _cap(d, r):
    """Area of the part of a disc of radius r beyond a line at distance d from its centre (numpy)."""
    x = np.clip(d / np.maximum(r, 1e-300), 0.0, 1.0)
    return r * r * (np.arccos(x) - x * np.sqrt(np.maximum(1.0 - x * x, 0.0)))


def _cut_by_plane(position, normal, u1, d1, d2, detector_z):
    """(d1, d2) with the detector plane's line merged in (numpy): where z = detector_z cuts the tangent
    plane, at (detector_z − z) / |g| along g, the tangent direction of steepest z ascent; it joins the
    nearest boundary when it lies on that side of the centre, else the opposite one, whichever is nearer."""
    g = np.zeros_like(normal)
    g[:, 2] = 1.0
    g = g - normal[:, 2:3] * normal
    slope = np.linalg.norm(g, axis=1)
    cuts = slope > 1e-9
    dist = np.maximum(np.where(cuts, (detector_z - position[:, 2]) / np.where(cuts, slope, 1.0), np.inf), 0.0)
    same_side = np.einsum("hj,hj->h", g, u1) > 0
    d1 = np.where(cuts & same_side, np.minimum(d1, dist), d1)
    d2 = np.where(cuts & ~same_side, np.minimum(d2, dist), d2)
    return d1, d2


# The compiled loop and numpy's einsum sum the same three-term dot products in different orders (numpy's
# summation order, SIMD width and use of FMA change between releases). An area is πr² less two caps, each
# from ~40 roundings of terms no larger than πr²; 256 ulp of πr² (5.7e-14 relative) bounds that with a wide
# margin (numpy 2.4 with numba 0.68 differ by at most 34 ulp of the area), while a wrong boundary or cap moves an
# area by a share of πr² many orders larger.
AREA_ROUNDING = 256 * np.finfo(float).eps


def _assert_same_areas(compiled, reference, radius):
    assert np.all(np.abs(compiled - reference) <= AREA_ROUNDING * np.pi * radius**2), (
        np.max(np.abs(compiled - reference) / (np.pi * radius**2)))


def test_compiled_boundary_search_is_the_numpy_one_to_rounding():
    """Points on and just off a tilted annulus (a cone-like bore face crossing the detector plane) and a
    50 µm strip, radii from 10 µm to 5 mm: every area equals the numpy formulation's to rounding, with and
    without the detector plane, for one radius and for the pair the view map asks for."""
    rng = np.random.default_rng(3)
    v_a, tri_a = _annulus(10.0, 14.0, 96)
    c, s = math.cos(0.4), math.sin(0.4)
    # tilted about x, then turned about z: its z spans the detector plane and its normal has three
    # non-zero components (how the plane's slope |g| is summed shows in the last bit)
    turn = np.array([[math.cos(0.3), -math.sin(0.3), 0], [math.sin(0.3), math.cos(0.3), 0], [0, 0, 1]])
    tilt = turn @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    v_a = v_a @ tilt.T
    v_s, tri_s, tags_s = _strip(0.05, 100.0, n=200)
    v = np.vstack([v_a, v_s + [0, 0, 30.0]])
    tri = np.vstack([tri_a, tri_s + len(v_a)])
    tags = np.concatenate([np.zeros(len(tri_a), int), tags_s + 1])
    fb = FaceBoundaries(v, tri, tags, 3)
    n = 4000
    rho, phi = rng.uniform(9.9, 14.1, n), rng.uniform(0, 2 * np.pi, n)
    on_annulus = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), np.zeros(n)])
    on_annulus = on_annulus @ tilt.T
    on_strip = np.column_stack([rng.uniform(0, 100, n), rng.uniform(-0.01, 0.06, n), np.full(n, 30.0)])
    pos = np.vstack([on_annulus, on_strip])
    # facet normals scattered by ~1° about the annulus's, as on a tessellated curved face
    wobble = tilt @ [0, 0, 1.0] + rng.normal(0.0, 0.02, (n, 3))
    nrm = np.vstack([wobble / np.linalg.norm(wobble, axis=1, keepdims=True), np.tile([0, 0, 1.0], (n, 1))])
    tag = np.repeat([0, 1], n)
    r = np.exp(rng.uniform(math.log(0.01), math.log(5.0), 2 * n))
    for detector_z in (None, 2.0):
        full, half = fb.inside_areas(pos, nrm, tag, (r, 0.5 * r), detector_z=detector_z)
        _assert_same_areas(full, _inside_area_numpy(fb, pos, nrm, tag, r, detector_z), r)
        _assert_same_areas(half, _inside_area_numpy(fb, pos, nrm, tag, 0.5 * r, detector_z), 0.5 * r)
        assert np.array_equal(fb.inside_area(pos, nrm, tag, r, detector_z=detector_z), full)
