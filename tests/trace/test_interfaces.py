"""Snell, TIR and Fresnel at a glass surface, checked against closed forms (Born & Wolf §1.5)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lensmount.errors import InputError
from lensmount.optics.snell import refract
from lensmount.physics.interfaces import (
    MGF2_DESIGN_WAVELENGTH_UM, MGF2_INDEX, Coating, fresnel_rt, parse_coating, reflectance)

UNCOATED = Coating("uncoated")
MGF2 = Coating("mgf2-quarter-wave")


def _rt(n1, n2, theta, coating=UNCOATED, wl=0.55):
    n = len(theta)
    return fresnel_rt(np.full(n, n1), np.full(n, n2), np.cos(theta), coating, np.full(n, wl))


@pytest.mark.parametrize("coating", [UNCOATED, MGF2])
@pytest.mark.parametrize("n1,n2", [(1.0, 1.5168), (1.5168, 1.0), (1.6, 1.45), (1.0, 1.9)])
def test_r_plus_t_is_one_at_all_angles(coating, n1, n2):
    theta = np.linspace(0.0, 0.5 * math.pi, 2001)
    rs, rp, ts, tp = _rt(n1, n2, theta, coating)
    # T comes from the admittance formula, not from 1 - R: this checks the algebra.
    np.testing.assert_allclose(rs + ts, 1.0, atol=1e-12)
    np.testing.assert_allclose(rp + tp, 1.0, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(n1=st.floats(1.0, 2.2), n2=st.floats(1.0, 2.2), c=st.floats(0.0, 1.0),
       wl=st.floats(0.35, 1.1), film=st.booleans())
def test_r_plus_t_hypothesis(n1, n2, c, wl, film):
    rs, rp, ts, tp = fresnel_rt(np.array([n1]), np.array([n2]), np.array([c]), MGF2 if film else UNCOATED,
                                np.array([wl]))
    for v in (rs, rp, ts, tp):
        assert np.all(np.isfinite(v)) and np.all((v >= 0) & (v <= 1))
    assert abs(rs[0] + ts[0] - 1.0) < 1e-9 and abs(rp[0] + tp[0] - 1.0) < 1e-9


def test_normal_incidence_closed_form():
    for n1, n2 in [(1.0, 1.5168), (1.7, 1.0)]:
        rs, rp, _, _ = _rt(n1, n2, np.array([0.0]))
        expected = ((n1 - n2) / (n1 + n2)) ** 2
        assert rs[0] == pytest.approx(expected, rel=1e-12)
        assert rp[0] == pytest.approx(expected, rel=1e-12)


def test_oblique_fresnel_closed_form():
    """Textbook s and p amplitude formulas at 30°, 60° for air -> 1.5."""
    n1, n2 = 1.0, 1.5
    th = np.radians([30.0, 60.0])
    tt = np.arcsin(n1 * np.sin(th) / n2)
    rs_ref = (np.sin(th - tt) / np.sin(th + tt)) ** 2
    rp_ref = (np.tan(th - tt) / np.tan(th + tt)) ** 2
    rs, rp, _, _ = _rt(n1, n2, th)
    np.testing.assert_allclose(rs, rs_ref, rtol=1e-12)
    np.testing.assert_allclose(rp, rp_ref, rtol=1e-12)


@pytest.mark.parametrize("n1,n2", [(1.0, 1.5168), (1.5168, 1.0)])
def test_brewster_angle_p_is_zero(n1, n2):
    brewster = math.atan(n2 / n1)
    rs, rp, _, _ = _rt(n1, n2, np.array([brewster]))
    assert rp[0] < 1e-20
    assert rs[0] > 0.01


@pytest.mark.parametrize("coating", [UNCOATED, MGF2, Coating("perfect-ar"), Coating("constant", 0.02)])
def test_total_internal_reflection_beyond_critical_angle(coating):
    n1, n2 = 1.5168, 1.0
    critical = math.asin(n2 / n1)
    theta = np.linspace(critical + 1e-9, 0.5 * math.pi, 500)
    rs, rp, ts, tp = _rt(n1, n2, theta, coating)
    np.testing.assert_array_equal(rs, 1.0)
    np.testing.assert_array_equal(rp, 1.0)
    np.testing.assert_array_equal(ts + tp, 0.0)
    below = _rt(n1, n2, np.array([critical - 1e-3]), coating)
    assert below[2][0] > 0 or coating.kind == "constant" and below[2][0] == pytest.approx(0.98)


def test_mgf2_quarter_wave_closed_form():
    """At its design wavelength and normal incidence a quarter-wave layer gives
    R = ((n0 ns - nf²) / (n0 ns + nf²))² (Macleod eq. 3.14)."""
    ns = 1.5168
    rs, rp, _, _ = _rt(1.0, ns, np.array([0.0]), MGF2, MGF2_DESIGN_WAVELENGTH_UM)
    expected = ((ns - MGF2_INDEX**2) / (ns + MGF2_INDEX**2)) ** 2
    assert rs[0] == pytest.approx(expected, rel=1e-12)
    # A quarter wave is the reflectance minimum in wavelength; far from it the layer helps less.
    wl = np.linspace(0.4, 0.8, 401)
    r = reflectance(np.ones_like(wl), np.full_like(wl, ns), np.ones_like(wl), MGF2, wl)
    assert abs(wl[np.argmin(r)] - MGF2_DESIGN_WAVELENGTH_UM) < 2e-3
    bare = ((1 - ns) / (1 + ns)) ** 2
    assert np.all(r < bare)


def test_perfect_ar_and_constant():
    theta = np.linspace(0.0, 1.5, 50)
    assert np.all(_rt(1.0, 1.5, theta, Coating("perfect-ar"))[0] == 0.0)
    rs, rp, ts, tp = _rt(1.0, 1.5, theta, parse_coating("R=0.01"))
    np.testing.assert_allclose(rs, 0.01)
    np.testing.assert_allclose(tp, 0.99)


def test_parse_coating_rejects_unknown_names():
    for bad in ("shiny", "R=1.5", "R=-0.1", "R="):
        with pytest.raises(InputError) as exc:
            parse_coating(bad, field="coatings.default")
        assert "coatings.default" in str(exc.value) and "perfect-ar" in str(exc.value)


@settings(max_examples=200, deadline=None)
@given(theta=st.floats(0.0, 1.5706), phi=st.floats(0.0, 6.283), n1=st.floats(1.0, 2.0), n2=st.floats(1.0, 2.0),
       flip=st.booleans())
def test_snell_vector_law(theta, phi, n1, n2, flip):
    """n1 sin θi = n2 sin θt, coplanar, unit length; TIR gives the mirror direction."""
    normal = np.array([[0.0, 0.0, -1.0 if flip else 1.0]])
    d = np.array([[math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]])
    t, tir, cos_i, cos_t = refract(d, normal, np.array([n1 / n2]))
    assert np.all(np.isfinite(t)) and abs(np.linalg.norm(t) - 1.0) < 1e-12
    if n1 * math.sin(theta) > n2 * (1 + 1e-12):
        assert tir[0] and t[0, 2] == pytest.approx(-d[0, 2], abs=1e-12)
    elif n1 * math.sin(theta) < n2 * (1 - 1e-9):
        assert not tir[0]
        sin_t = math.hypot(t[0, 0], t[0, 1])
        assert n1 * math.sin(theta) == pytest.approx(n2 * sin_t, abs=1e-9)
        assert t[0, 2] > 0  # continues forward
        # Coplanar: the tangential part keeps the incident azimuth.
        if math.sin(theta) > 1e-6:
            assert np.cross(d[0], t[0]) @ np.array([0, 0, 1.0]) == pytest.approx(0.0, abs=1e-9)
