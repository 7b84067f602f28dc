"""Each model against closed forms, its parameter checks, and its guards against NaN/Inf."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from bsdf_support import incidence, mirror_of
from lensmount.errors import InputError
from lensmount.physics.bsdf import make_bsdf
from lensmount.physics.sampler import stream


# -- closed forms ---------------------------------------------------------------------------

@pytest.mark.parametrize("deg", [0.0, 30.0, 60.0, 85.0, 89.99])
def test_lambertian_is_rho_over_pi_and_weight_rho(deg):
    bsdf = make_bsdf("lambertian", reflectance=0.1)
    wi, n = incidence(deg, 1000)
    wo, weight, pdf = bsdf.sample(wi, n, stream(1, "lambert").random((1000, 2)))
    np.testing.assert_allclose(bsdf.eval(wi, wo, n), 0.1 / math.pi, rtol=1e-15)
    np.testing.assert_allclose(weight, 0.1, rtol=1e-15)
    np.testing.assert_allclose(pdf, wo[:, 2] / math.pi, rtol=1e-12)
    np.testing.assert_allclose(bsdf.albedo(wi, n), 0.1)
    assert bsdf.tis == 0.1 and math.isinf(bsdf.lobe_half_width_deg)


@pytest.mark.parametrize("deg", [0.0, 30.0, 85.0])
def test_mirror_reflects_along_the_mirror_direction_with_weight_r(deg):
    bsdf = make_bsdf("mirror", reflectance=0.9)
    wi, n = incidence(deg, 10)
    wo, weight, pdf = bsdf.sample(wi, n, np.zeros((10, 2)))
    np.testing.assert_allclose(wo, mirror_of(wi, n), atol=1e-15)
    np.testing.assert_allclose(weight, 0.9)
    assert np.all(pdf == 1.0) and bsdf.is_delta
    assert np.all(bsdf.eval(wi, wo, n) == 0.0) and np.all(bsdf.pdf(wi, wo, n) == 0.0)
    np.testing.assert_allclose(bsdf.albedo(wi, n), 0.9)
    assert make_bsdf("mirror").reflectance == 1.0


def test_absorber_reflects_nothing():
    bsdf = make_bsdf("absorber")
    wi, n = incidence(30.0, 10)
    wo, weight, pdf = bsdf.sample(wi, n, np.full((10, 2), 0.5))
    assert bsdf.is_black and bsdf.tis == 0.0
    assert np.all(weight == 0.0) and np.all(pdf == 0.0) and np.all(np.isfinite(wo))
    assert np.all(bsdf.eval(wi, wo, n) == 0.0) and np.all(bsdf.albedo(wi, n) == 0.0)


@pytest.mark.parametrize("A,B", [(1e-3, 1e-4), (0.05, 0.3)])
def test_abg_tis_closed_form_g2(A, B):
    """g = 2: ∫_{|β|<1} A/(B + β²) d²β = πA ln((1 + B)/B)."""
    assert make_bsdf("abg", A=A, B=B, g=2.0).tis == pytest.approx(math.pi * A * math.log1p(1.0 / B), rel=1e-7)


@pytest.mark.parametrize("deg", [0.0, 40.0, 89.0])
def test_abg_flat_g0_is_lambertian(deg):
    """g = 0: f = A/(B + 1) everywhere, so albedo = πA/(B + 1) at any incidence."""
    bsdf = make_bsdf("abg", A=0.05, B=0.01, g=0.0)
    wi, n = incidence(deg, 1)
    assert bsdf.tis == pytest.approx(math.pi * 0.05 / 1.01, rel=1e-9)
    assert bsdf.albedo(wi, n)[0] == pytest.approx(math.pi * 0.05 / 1.01, rel=1e-6)


def test_abg_tis_general_g_against_scipy_quad():
    A, B, g = 2e-3, 3e-3, 1.7
    ref, _ = integrate.quad(lambda r: A / (B + r**g) * 2 * math.pi * r, 0, 1, points=[B ** (1 / g)], limit=200)
    assert make_bsdf("abg", A=A, B=B, g=g).tis == pytest.approx(ref, rel=1e-7)


def test_harvey_tis_closed_form_s_minus_2():
    """S = −2: ∫ b0/(1 + β²/L²) d²β = π b0 L² ln(1 + 1/L²)."""
    b0, L = 10.0, 0.01
    assert make_bsdf("harvey", b0=b0, L=L, S=-2.0).tis == pytest.approx(math.pi * b0 * L * L * math.log1p(1 / L**2),
                                                                         rel=1e-7)


@pytest.mark.parametrize("model,params", [("abg", {"A": 1e-3, "B": 1e-4, "g": 2.0}),
                                          ("harvey", {"b0": 0.15, "L": 0.2, "S": -2.5})])
def test_direction_cosine_albedo_never_exceeds_tis(model, params):
    """A lobe decreasing in |β − β0| collects the most over the unit disc when β0 = 0 (normal incidence)."""
    bsdf = make_bsdf(model, **params)
    deg = np.linspace(0.0, 89.99, 200)
    wi = np.stack([np.sin(np.radians(deg)), 0 * deg, np.cos(np.radians(deg))], axis=1)
    albedo = bsdf.albedo(wi, np.tile([0.0, 0.0, 1.0], (200, 1)))
    assert np.all(albedo <= bsdf.tis * (1 + 1e-9)) and albedo[-1] < 0.7 * bsdf.tis


def test_abg_eval_is_the_formula_in_direction_cosines():
    bsdf = make_bsdf("abg", A=1e-3, B=1e-4, g=2.0)
    wi, n = incidence(30.0, 1)
    wo = np.array([[-math.sin(math.radians(31.0)), 0.0, math.cos(math.radians(31.0))]])
    d_beta = math.sin(math.radians(31.0)) - math.sin(math.radians(30.0))
    assert bsdf.eval(wi, wo, n)[0] == pytest.approx(1e-3 / (1e-4 + d_beta**2), rel=1e-9)


def test_gaussian_half_width_is_hwhm_of_the_lobe():
    """The lobe shape p falls to half its peak at θ = half-width from the mirror direction."""
    for hw in (0.01, 0.05, 5.0, 30.0):
        bsdf = make_bsdf("gaussian", reflectance=0.05, half_width_deg=hw)
        wi, n = incidence(20.0, 2)
        r = mirror_of(wi, n)[0]
        t = math.radians(20.0 - hw)  # rotate r by hw in the plane of incidence
        wo = np.array([r, [-math.sin(t), 0.0, math.cos(t)]])
        p = bsdf.pdf(wi, wo, n)
        assert p[1] / p[0] == pytest.approx(0.5, rel=1e-6)


def test_gaussian_normalisation_against_scipy_quad():
    """At normal incidence, albedo = ρ N ∫_hemisphere p(θ) 2cosθ/(1 + cosθ) dω = ρ: check N independently."""
    hw = 30.0
    bsdf = make_bsdf("gaussian", reflectance=0.4, half_width_deg=hw)
    kappa = math.log(2) / (2 * math.sin(math.radians(hw) / 2) ** 2)
    p = lambda t: kappa * math.exp(-kappa * (1 - math.cos(t))) / (2 * math.pi * -math.expm1(-2 * kappa))
    lobe, _ = integrate.quad(lambda t: p(t) * 2 * math.cos(t) / (1 + math.cos(t)) * 2 * math.pi * math.sin(t),
                             0, math.pi / 2)
    wi, n = incidence(0.0, 1)
    wo = np.array([[0.0, 0.0, 1.0]])
    assert bsdf.eval(wi, wo, n)[0] == pytest.approx(0.4 / lobe * p(0.0), rel=1e-7)


def test_gaussian_narrow_lobe_albedo_is_rho_until_the_horizon_clips_it():
    bsdf = make_bsdf("gaussian", reflectance=0.05, half_width_deg=0.05)
    deg = np.array([0.0, 30.0, 60.0, 85.0, 89.9, 89.99])
    wi = np.stack([np.sin(np.radians(deg)), 0 * deg, np.cos(np.radians(deg))], axis=1)
    albedo = bsdf.albedo(wi, np.tile([0.0, 0.0, 1.0], (len(deg), 1)))
    np.testing.assert_allclose(albedo[:4], 0.05, rtol=1e-4)
    assert albedo[-1] < 0.045  # a lobe of 0.05° half-width, 0.01° above the horizon


def test_wide_gaussian_with_too_much_reflectance_is_an_error():
    with pytest.raises(InputError) as err:
        make_bsdf("gaussian", reflectance=0.9, half_width_deg=60.0)
    assert err.value.field == "reflectance" and "0.57" in err.value.valid


# -- parameter checks ------------------------------------------------------------------------

@pytest.mark.parametrize("model,params,field", [
    ("lambertian", {"reflectance": 1.5}, "reflectance"),
    ("lambertian", {"reflectance": -0.1}, "reflectance"),
    ("lambertian", {"reflectance": float("nan")}, "reflectance"),
    ("lambertian", {"reflectance": "high"}, "reflectance"),
    ("lambertian", {"reflectance": True}, "reflectance"),
    ("lambertian", {}, "reflectance"),
    ("lambertian", {"reflectance": 0.1, "colour": 2}, "colour"),
    ("gaussian", {"reflectance": 0.05, "half_width_deg": 0.0}, "half_width_deg"),
    ("gaussian", {"reflectance": 0.05, "half_width_deg": -2.0}, "half_width_deg"),
    ("gaussian", {"reflectance": 0.05, "half_width": 5.0}, "half_width"),
    ("abg", {"A": 1.0, "B": 0.01, "g": 2.0}, "A"),          # TIS = π ln 101 ≈ 14.5
    ("abg", {"A": 1e-3, "B": 0.0, "g": 2.0}, "B"),
    ("abg", {"A": -1e-3, "B": 1e-3, "g": 2.0}, "A"),
    ("abg", {"A": 1e-3, "B": 1e-3, "g": -1.0}, "g"),
    ("harvey", {"b0": 100.0, "L": 0.1, "S": -2.0}, "b0"),   # TIS ≈ 14.5
    ("harvey", {"b0": 1.0, "L": 0.0, "S": -2.0}, "L"),
    ("harvey", {"b0": 1.0, "L": 0.1, "S": 1.0}, "S"),
    ("mirror", {"reflectance": 2.0}, "reflectance"),
    ("absorber", {"reflectance": 0.0}, "reflectance"),
    ("velvet", {}, "model"),
])
def test_bad_parameters_are_input_errors_naming_the_field(model, params, field):
    with pytest.raises(InputError) as err:
        make_bsdf(model, **params)
    assert err.value.field == field and err.value.valid


def test_tis_just_below_one_is_accepted():
    A = 0.99 / (math.pi * math.log1p(1.0 / 0.01))
    assert make_bsdf("abg", A=A, B=0.01, g=2.0).tis == pytest.approx(0.99, rel=1e-7)


def test_model_names_are_case_insensitive_and_public_alias_exports_them():
    import lensmount.physics.bsdf as public
    assert isinstance(public.make_bsdf("Lambertian", reflectance=0.1), public.Lambertian)
    assert set(public.BSDFS.names()) == {"absorber", "lambertian", "gaussian", "abg", "harvey", "mirror", "tabulated"}
    assert public.BSDFS.entry("tabulated").factory is public.Tabulated


# -- no NaN or Inf, whatever the geometry ---------------------------------------------------

ALL = [("absorber", {}), ("lambertian", {"reflectance": 0.5}), ("mirror", {"reflectance": 0.9}),
       ("gaussian", {"reflectance": 0.5, "half_width_deg": 0.01}),
       ("gaussian", {"reflectance": 0.5, "half_width_deg": 5.0}),
       ("gaussian", {"reflectance": 0.44, "half_width_deg": 90.0}),
       ("abg", {"A": 1e-6, "B": 1e-8, "g": 2.0}), ("abg", {"A": 0.3, "B": 1.0, "g": 0.0}),
       ("harvey", {"b0": 1e3, "L": 1e-4, "S": -2.0}), ("harvey", {"b0": 0.3, "L": 1.0, "S": 0.0})]
BSDFS = [make_bsdf(m, **p) for m, p in ALL]

# Polar angles that break naive code: exactly along n, grazing, exactly at the horizon.
SPECIAL_COS = [1.0, 1.0 - 1e-16, 0.5, 1e-4, 1e-9, 1e-12, 1e-300, 0.0]
cosines = st.one_of(st.sampled_from(SPECIAL_COS), st.floats(0.0, 1.0))
azimuths = st.floats(0.0, 2 * math.pi)
uniforms = st.one_of(st.sampled_from([0.0, 0.5, 1.0 - 2**-53]), st.floats(0.0, 1.0, exclude_max=True))


def _direction(c, phi):
    s = math.sqrt(max(1 - c * c, 0.0))
    return [s * math.cos(phi), s * math.sin(phi), c]


@settings(max_examples=300, deadline=None)
@given(ci=cosines, co=cosines, pi=azimuths, po=azimuths, u0=uniforms, u1=uniforms,
       specular=st.booleans())
def test_no_nan_or_inf_anywhere(ci, co, pi, po, u0, u1, specular):
    wi = np.array([_direction(ci, pi)])
    wo = np.array([_direction(co, po)]) if not specular else np.array([_direction(ci, pi + math.pi)])
    n = np.array([[0.0, 0.0, 1.0]])
    u = np.array([[u0, u1]])
    for bsdf in BSDFS:
        f, p, a = bsdf.eval(wi, wo, n), bsdf.pdf(wi, wo, n), bsdf.albedo(wi, n)
        w_s, weight, pdf = bsdf.sample(wi, n, u)
        for value in (f, p, a, w_s, weight, pdf):
            assert np.all(np.isfinite(value)), bsdf
        assert f[0] >= 0 and p[0] >= 0 and 0 <= a[0] <= 1 + 1e-12 and weight[0] >= 0 and pdf[0] >= 0
        assert abs(np.linalg.norm(w_s) - 1.0) < 1e-9
        if weight[0] > 0:
            assert w_s[0, 2] > 0 and pdf[0] > 0  # live lanes point above the surface


def test_grazing_narrow_lobe_batch_stays_finite_and_unbiased():
    """0.01° Gaussian at 89.99° incidence: half the lobe below the horizon; finite, mean weight = albedo."""
    bsdf = make_bsdf("gaussian", reflectance=0.5, half_width_deg=0.01)
    count = 200_000
    wi, n = incidence(89.99, count)
    wo, weight, pdf = bsdf.sample(wi, n, stream(5, "grazing").random((count, 2)))
    assert np.all(np.isfinite(weight)) and np.all(np.isfinite(pdf)) and pdf.max() < 1e9
    albedo = bsdf.albedo(wi[:1], n[:1])[0]
    assert 0.2 < albedo < 0.5
    assert abs(weight.mean() - albedo) < 4 * weight.std() / math.sqrt(count)


def test_below_horizon_arguments_give_zero():
    n = np.array([[0.0, 0.0, 1.0]] * 2)
    up = np.array([[0.6, 0.0, 0.8]] * 2)
    down = np.array([[-0.6, 0.0, -0.8], [0.6, 0.0, -0.8]])
    for bsdf in BSDFS:
        assert np.all(bsdf.eval(up, down, n) == 0) and np.all(bsdf.eval(down, up, n) == 0)
        assert np.all(bsdf.pdf(up, down, n) == 0) and np.all(bsdf.albedo(down, n) == 0)
        assert np.all(bsdf.sample(down, n, np.full((2, 2), 0.3))[1] == 0)


# -- albedo: the table against the quadrature, the quadrature against scipy ----------------

TABULATED = [("gaussian", {"reflectance": 0.5, "half_width_deg": 0.01}),
             ("gaussian", {"reflectance": 0.5, "half_width_deg": 5.0}),
             ("gaussian", {"reflectance": 0.44, "half_width_deg": 90.0}),
             ("abg", {"A": 1e-5, "B": 1e-6, "g": 3.0}), ("abg", {"A": 0.02, "B": 0.05, "g": 1.5}),
             ("harvey", {"b0": 1e3, "L": 1e-4, "S": -2.0}), ("harvey", {"b0": 0.15, "L": 0.2, "S": -2.5})]


@pytest.mark.parametrize("model,params", TABULATED)
def test_albedo_table_matches_its_quadrature(model, params):
    bsdf = make_bsdf(model, **params)
    rng = stream(3, "albedo-table")
    elevation = np.concatenate([rng.uniform(0, math.pi / 2, 300), 10 ** rng.uniform(-8, 0, 300)])
    ci = np.sin(elevation)
    wi = np.stack([np.cos(elevation), 0 * ci, ci], axis=1)
    table = bsdf.albedo(wi, np.tile([0.0, 0.0, 1.0], (len(ci), 1)))
    np.testing.assert_allclose(table, bsdf._albedo_exact(ci), rtol=1e-6)


@pytest.mark.parametrize("deg", [30.0, 70.0, 88.0])
def test_abg_albedo_quadrature_against_scipy(deg):
    """∫_{|β|<1} f(|β − β0|) d²β in polar coordinates about the origin, by scipy's adaptive quadrature."""
    A, B, g = 0.02, 0.05, 1.5
    bsdf = make_bsdf("abg", A=A, B=B, g=g)
    b = math.sin(math.radians(deg))
    f = lambda phi, r: A / (B + math.hypot(r * math.cos(phi) - b, r * math.sin(phi)) ** g) * r
    ref, _ = integrate.dblquad(f, 0, 1, 0, math.pi, epsabs=1e-12, epsrel=1e-9)
    assert bsdf._albedo_exact(np.array([math.cos(math.radians(deg))]))[0] == pytest.approx(2 * ref, rel=1e-6)


@pytest.mark.parametrize("deg", [30.0, pytest.param(80.0, marks=pytest.mark.slow),
                                 pytest.param(89.0, marks=pytest.mark.slow)])
def test_gaussian_albedo_quadrature_against_scipy(deg):
    """∫ f cosθo dω over the hemisphere, in the lobe's own (x = 1 − cosθ, φ) coordinates (dω = dx dφ)."""
    bsdf = make_bsdf("gaussian", reflectance=0.3, half_width_deg=5.0)
    wi, n = incidence(deg, 1)
    r = mirror_of(wi, n)[0]
    e1 = np.array([0.0, 0.0, 1.0]) - r[2] * r
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(r, e1)

    def integrand(phi, x):
        s = math.sqrt(max(x * (2 - x), 0.0))
        wo = (1 - x) * r + s * math.cos(phi) * e1 + s * math.sin(phi) * e2
        return bsdf.eval(wi, wo[None, :], n)[0] * max(wo[2], 0.0)

    x_max = 0.1  # 1 − cos(25.8°): p there is e^{−κ·0.1} ≈ 1e-8 of its peak
    ref, _ = integrate.dblquad(integrand, 0, x_max, 0, 2 * math.pi, epsabs=1e-10, epsrel=1e-8)
    assert bsdf.albedo(wi, n)[0] == pytest.approx(ref, rel=1e-5)
