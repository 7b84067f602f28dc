"""Forbes Q-type aspheres (lensmount.optics.qtype) against an independent evaluation.

The reference is not the production recurrence: the polynomials come from their defining inner
products (Forbes, Opt. Express 15, 5218 (2007)) by Gram–Schmidt, the Gram matrices exact in
rational arithmetic and the orthonormalisation in 50-digit mpmath; the sag is then summed in
mpmath and differentiated numerically by mpmath. Qbfs: orthonormal in slope,
⟨S_m' S_n'⟩ = δ_mn with S_m(u) = u²(1 - u²) Q_m(u²) and ⟨f⟩ = ∫_0^1 f (1 - u²)^-½ du / (π/2); the
sign convention of Forbes's list (Q_0 = 1, Q_1 = (13 - 16x)/√19: Q_m(0) > 0). Qcon: orthogonal in
sag with weight x⁴ on [0, 1] (the Jacobi P^(0,4)(2x - 1)), normalised by Q_m(1) = 1.
"""

from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction
from math import comb
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest

from lensmount.errors import InputError
from lensmount.optics.glass import medium
from lensmount.optics.io.lens_toml import format_lens_toml, parse_lens_toml
from lensmount.optics.io.zemax import read_zmx
from lensmount.optics.paraxial import paraxial
from lensmount.optics.profiles import Profile
from lensmount.optics.qtype import QType
from lensmount.optics.realrays import trace

mp.mp.dps = 50
ASL5040 = Path(__file__).parent / "corpus" / "thorlabs-ASL5040-UV-qbfs-utf16.zmx"
TOL_MM = 1e-9


def _wallis(p: int) -> Fraction:
    """∫_0^1 u^(2p) (1 - u²)^-½ du / (π/2) = C(2p, p) / 4^p."""
    return Fraction(comb(2 * p, p), 4**p)


def _poly_mul(a, b):
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def _orthonormal(gram, n):
    """Rows: coefficients (in x^0..x^(n-1)) of the orthonormal polynomials of the Gram matrix, by
    Gram–Schmidt (Cholesky) in mpmath."""
    g = mp.matrix([[mp.mpf(gram[j][k].numerator) / gram[j][k].denominator for k in range(n)] for j in range(n)])
    lower = mp.cholesky(g)
    inv = lower**-1
    return [[inv[m, k] for k in range(n)] for m in range(n)]


def qbfs_reference(n: int):
    """Q^bfs_0..Q^bfs_(n-1) as mpmath coefficient lists in x = u²."""
    # S_k(u) = u^(2k+2) - u^(2k+4); S_k'(u) = (2k+2) u^(2k+1) - (2k+4) u^(2k+3); the products are
    # even in u, so every Gram entry is a sum of Wallis integrals.
    def d(k):  # coefficients of S_k' / u in powers of u²
        c = [Fraction(0)] * (k + 2)
        c[k], c[k + 1] = Fraction(2 * k + 2), Fraction(-(2 * k + 4))
        return c

    gram = [[sum(c * _wallis(p + 1) for p, c in enumerate(_poly_mul(d(j), d(k)))) for k in range(n)]
            for j in range(n)]
    rows = _orthonormal(gram, n)
    return [[-v for v in r] if r[0] < 0 else r for r in rows]


def qcon_reference(n: int):
    """Q^con_0..Q^con_(n-1): orthogonal under ∫_0^1 x⁴ p q dx, Q_m(1) = 1."""
    gram = [[Fraction(1, 5 + j + k) for k in range(n)] for j in range(n)]
    rows = _orthonormal(gram, n)
    return [[v / sum(r) for v in r] for r in rows]


def reference_sag(q: QType, c: float, k: float):
    """z(r) in mpmath from the reference polynomials."""
    basis = (qbfs_reference if q.form == "qbfs" else qcon_reference)(len(q.coefficients))
    a = [mp.mpf(v) for v in q.coefficients]
    c, k, rn = mp.mpf(c), mp.mpf(k), mp.mpf(q.norm_radius)

    def z(r):
        x = (r / rn) ** 2
        total = sum(am * sum(b * x**i for i, b in enumerate(row)) for am, row in zip(a, basis))
        root = mp.sqrt(1 - (1 + k) * c * c * r * r)
        base = c * r * r / (1 + root)
        # Forbes 2011: the Qbfs departure is along the base conic's normal
        phi = mp.sqrt(1 - k * c * c * r * r) / root
        return base + (x * x * total if q.form == "qcon" else x * (1 - x) * total * phi)

    return z


def test_reference_polynomials_are_forbes_s():
    """The Gram–Schmidt reference reproduces the closed forms Forbes lists (and Jacobi's P^(0,4))."""
    q1 = qbfs_reference(2)[1]
    assert float(q1[0]) == pytest.approx(13 / math.sqrt(19), rel=1e-15)
    assert float(q1[1]) == pytest.approx(-16 / math.sqrt(19), rel=1e-15)
    c1 = qcon_reference(2)[1]  # P_1^(0,4)(t) = 3t - 2 with t = 2x - 1
    assert [float(v) for v in c1] == pytest.approx([-5.0, 6.0], rel=1e-15)


CASES = [
    # the Thorlabs ASL5040-UV face as its file gives it (Qbfs on a conic), mm
    (QType("qbfs", 27.0, (-0.8148370167576, -0.32311, 0.10591, -0.05058, 0.00987, -0.0022)),
     0.05756078762782423, -0.67609120640407927, 22.86),
    # Forbes's own setting: Qbfs on its best-fit sphere, many terms
    (QType("qbfs", 12.5, tuple(0.05 * (-0.6) ** m for m in range(13))), 1 / 40.0, 0.0, 12.5),
    # Qcon on a hyperboloid and on an oblate ellipsoid
    (QType("qcon", 10.0, tuple(2e-3 * (0.7) ** m * (-1) ** m for m in range(11))), -1 / 25.0, -1.8, 10.0),
    (QType("qcon", 6.0, (0.01, -0.004, 0.002, 1e-3, -5e-4)), 1 / 15.0, 0.4, 6.0),
]


@pytest.mark.parametrize("q, c, k, aperture", CASES)
def test_sag_and_slope_match_independent_evaluation(q, c, k, aperture):
    """Sag and dz/dr to 1e-9 mm (and 1e-9 in slope) over the aperture, u up to 1 included."""
    prof = Profile(c, k, (), q)
    z_ref = reference_sag(q, c, k)
    r = np.concatenate([np.linspace(0.0, aperture, 201), aperture * (1 - np.logspace(-12, -3, 10))])
    sag = prof.sag(r * r)
    slope = prof.slope(r * r) * r
    ref_sag = np.array([float(z_ref(mp.mpf(float(x)))) for x in r])
    ref_slope = np.array([float(mp.diff(z_ref, mp.mpf(float(x)))) for x in r])
    assert np.max(np.abs(sag - ref_sag)) < TOL_MM
    assert np.max(np.abs(slope - ref_slope)) < TOL_MM


def test_beyond_the_normalisation_radius_and_the_base_s_reach():
    """u > 1 is the polynomials' extrapolation (finite, still the reference); beyond the base conic's
    reach the sag and slope are inf, never NaN; so are absurd radii."""
    q, c, k, _ = CASES[0]
    prof = Profile(c, k, (), q)
    z_ref = reference_sag(q, c, k)
    for r in (28.0, 30.0):  # u = 1.04, 1.11, still inside the conic's 30.5 mm reach
        assert abs(float(prof.sag(np.array([r * r]))[0]) - float(z_ref(mp.mpf(r)))) < 1e-8
    reach = prof.max_radius()
    r2 = np.array([(reach * 1.0001) ** 2, 1e30, 1e300, np.inf])
    for p in (prof, Profile(0.02, 0.0, (), QType("qcon", 5.0, (1.0, 2.0, 3.0)))):
        for values in (p.sag(r2), p.slope(r2)):
            assert not np.isnan(values).any()
    assert np.isinf(prof.sag(r2)).all()


def test_grazing_and_steep_rays_hit_the_surface_or_miss_cleanly():
    """Profile.intersect of rays from every direction: hits lie on the surface to 1e-9 mm, misses
    are inf, no NaN."""
    q, c, k, aperture = CASES[0]
    prof = Profile(c, k, (), q)
    rng = np.random.default_rng(3)
    n = 4000
    o = np.column_stack([rng.uniform(-30, 30, n), rng.uniform(-30, 30, n), rng.uniform(-20, -1, n)])
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) * rng.choice([1e-4, 1e-2, 1.0, 10.0], n)  # grazing to steep
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = prof.intersect(o, d)
    assert not np.isnan(t).any()
    hit = np.isfinite(t)
    p = o[hit] + t[hit, None] * d[hit]
    r2 = p[:, 0] ** 2 + p[:, 1] ** 2
    assert hit.sum() > n // 10
    assert np.max(np.abs(p[:, 2] - prof.sag(r2))) < TOL_MM


def _fit_even_asphere(prof: Profile, c_vertex: float, k: float, h: float, terms: int = 10):
    """(A4, A6, ...) fitting prof's sag on [0, h] as the conic (c_vertex, k) plus even terms; least
    squares in r/h (the columns stay conditioned) and returned per mm. Also the fit's worst sag
    and slope residuals."""
    r = np.linspace(0.0, h, 2000)
    base = Profile(c_vertex, k)
    target = prof.sag(r * r) - base.sag(r * r)
    cols = np.column_stack([(r / h) ** (2 * i + 4) for i in range(terms)])
    scaled = np.linalg.lstsq(cols, target, rcond=None)[0]
    a = tuple(s / h ** (2 * i + 4) for i, s in enumerate(scaled))
    fitted = Profile(c_vertex, k, a)
    rr = np.linspace(0.0, h, 20001)
    dz = np.max(np.abs(fitted.sag(rr * rr) - prof.sag(rr * rr)))
    ds = np.max(np.abs((fitted.slope(rr * rr) - prof.slope(rr * rr)) * rr))
    return a, dz, ds


def test_qbfs_lens_traces_as_the_even_asphere_fitted_to_it():
    """Thorlabs' ASL5040-UV (a Qbfs face on a conic) against the same lens with that face replaced
    by an even asphere fitted to its sag: the same real rays at the image plane, within what the
    fit's residual allows (a slope error s bends a ray by at most (n - 1) s; over the ~50 mm to the
    image that moves it (n - 1) s L, and a sag error dz moves the hit by dz tan(angle) < dz)."""
    lens = read_zmx(ASL5040)
    face = lens.surfaces[0]
    h = face.clear_semi_diameter
    a, dz, ds = _fit_even_asphere(Profile.of(face), face.vertex_curvature, face.conic, h * 1.001)
    even = lens.with_surfaces([replace(face, radius=1.0 / face.vertex_curvature, qtype=None, aspheric=a),
                               *lens.surfaces[1:]])
    assert even.surfaces[0].vertex_curvature == pytest.approx(face.vertex_curvature, rel=1e-15)
    ys = np.linspace(0.0, h, 301)
    o = np.column_stack([np.zeros_like(ys), ys, np.full_like(ys, -1.0)])
    d = np.tile([0.0, 0.0, 1.0], (len(ys), 1))
    wl = lens.primary_wavelength_um
    got = trace(lens, o, d, wl, clip=False)
    ref = trace(even, o, d, wl, clip=False)
    assert not got.vignetted.any() and not ref.vignetted.any()
    n_glass = 1.4696  # fused silica at 405 nm, within 1e-4
    length = lens.image_z
    allowed = 2.0 * ((n_glass - 1.0) * ds * length + dz)
    miss = np.max(np.abs(got.image_points[:, 1] - ref.image_points[:, 1]))
    print(f"fit residual: sag {dz:.2e} mm, slope {ds:.2e}; image-plane difference {miss:.2e} mm "
          f"(allowed {allowed:.2e} mm)")
    assert dz < 1e-5  # the fit is a close stand-in, else the comparison says little
    assert miss < allowed
    # and the Q-type is not trivially the conic: the departure moves the marginal ray by millimetres
    bare = trace(lens.with_surfaces([replace(face, qtype=None), *lens.surfaces[1:]]), o, d, wl, clip=False)
    assert np.max(np.abs(bare.image_points[:, 1] - got.image_points[:, 1])) > 100 * allowed


def test_asl5040_is_the_corrected_asphere_thorlabs_sells():
    """Qbfs's u² term is part of the vertex curvature: EFL 40 mm (Thorlabs' f), the paraxial focus
    at 405 nm is the file's image plane (a solve OpticStudio wrote to full precision), and every zone
    of the NA 0.65 beam crosses the axis there too (the vendor's design: an asphere free of
    spherical aberration; with the Qbfs departure taken along the axis, or the face read as Qcon,
    the zones spread over 0.6 mm and 5 mm)."""
    lens = read_zmx(ASL5040)
    fo = paraxial(lens)
    face = lens.surfaces[0]
    q = face.qtype
    at_vertex = sum(mp.mpf(a) * row[0] for a, row in zip(q.coefficients, qbfs_reference(len(q.coefficients))))
    c_vertex = face.curvature + 2 * float(at_vertex) / q.norm_radius**2  # z ≈ (c + 2 S(0)/r_n²) r²/2
    n = float(medium(face.material)(np.array([lens.primary_wavelength_um]))[0])
    assert fo.efl == pytest.approx(1.0 / ((n - 1.0) * c_vertex), rel=1e-9)  # plano-convex: the front's power
    assert fo.efl == pytest.approx(40.0, abs=2e-3)
    assert fo.image_z == pytest.approx(lens.image_z, abs=1e-3)
    ys = np.linspace(0.1, lens.surfaces[0].clear_semi_diameter, 50)
    rays = trace(lens, np.column_stack([0 * ys, ys, -np.ones_like(ys)]), np.tile([0.0, 0.0, 1.0], (50, 1)))
    p, d = rays.points[-2], rays.directions[-2]
    z_cross = p[:, 2] - p[:, 1] * d[:, 2] / d[:, 1]
    assert np.max(np.abs(z_cross - lens.image_z)) < 2e-3


def test_lens_toml_round_trip_and_refusals():
    lens = read_zmx(ASL5040)
    back, _ = parse_lens_toml(format_lens_toml(lens))
    assert back.surfaces[0].qtype == lens.surfaces[0].qtype
    text = format_lens_toml(lens)
    for bad, field in (('form = "qbfs"', 'form = "qxx"'), ("norm_radius = 27.0", "norm_radius = 0.0"),
                       ("norm_radius = 27.0", "norm_radius = 27.0, terms = 6")):
        assert bad in text
        with pytest.raises(InputError) as err:
            parse_lens_toml(text.replace(bad, field, 1))
        assert "surface" in str(err.value) and "qtype" in str(err.value)


def _qed_file(tmp_path, xdat: dict, parm: dict | None = None, semi_diameter: float = 5.0):
    """A one-element lens whose front face is OpticStudio's Q-type surface."""
    lines = ["VERS 200914", "MODE SEQ", "UNIT MM X W X CM MR CPMM", "ENPD 8", "WAVM 1 0.5875618 1", "PWAV 1",
             "SURF 0", "  TYPE STANDARD", "  CURV 0.0", "  DISZ INFINITY",
             "SURF 1", "  STOP", "  TYPE QED_TYPE", "  CURV 0.04", "  CONI -0.5", "  DISZ 4", "  GLAS N-BK7",
             f"  DIAM {semi_diameter} 1 0 0 1 \"\""]
    lines += [f"  XDAT {k} {v} 0 0 1 0 0 \"\"" for k, v in xdat.items()]
    lines += [f"  PARM {k} {v}" for k, v in (parm or {}).items()]
    lines += ["SURF 2", "  TYPE STANDARD", "  CURV -0.01", "  DISZ 40", f"  DIAM {semi_diameter} 1 0 0 1 \"\"",
              "SURF 3", "  TYPE STANDARD", "  CURV 0.0", "  DISZ 0"]
    path = tmp_path / "qed.zmx"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_qed_type_reads_both_forms_in_lens_units(tmp_path):
    qcon = read_zmx(_qed_file(tmp_path, {1: 1, 2: 3, 3: 6.0, 4: 0.01, 5: -0.002, 6: 3e-4}))
    assert qcon.surfaces[0].qtype == QType("qcon", 6.0, (0.01, -0.002, 3e-4))
    assert qcon.surfaces[0].vertex_curvature == 0.04  # u⁴: no paraxial change
    text = _qed_file(tmp_path, {1: 0, 2: 2, 3: 6.0, 4: 0.01, 5: -0.002}).read_text().replace("UNIT MM", "UNIT CM")
    (tmp_path / "cm.zmx").write_text(text)
    qbfs = read_zmx(tmp_path / "cm.zmx")
    assert qbfs.surfaces[0].qtype == QType("qbfs", 60.0, (0.1, -0.02))


@pytest.mark.parametrize("xdat, parm, says", [
    ({1: 2, 2: 1, 3: 6.0, 4: 0.01}, None, "form 2"),
    ({1: 0, 2: 1, 3: 0.0, 4: 0.01}, None, "normalisation radius 0"),
    ({1: 0, 2: 1.5, 3: 6.0, 4: 0.01}, None, "1.5 terms"),
    ({1: 0, 2: 1, 3: 6.0, 4: 0.01, 5: 0.3}, None, "extra data 5"),
    ({1: 0, 2: 1, 3: 6.0, 4: 0.01}, {1: 2.0}, "parameter 1"),
])
def test_qed_type_it_cannot_read_is_refused_naming_surface_and_line(tmp_path, xdat, parm, says):
    with pytest.raises(InputError) as err:
        read_zmx(_qed_file(tmp_path, xdat, parm))
    msg = str(err.value)
    assert "surface 1 (Q-type asphere, QED_TYPE)" in msg and says in msg and err.value.line is not None


def test_q_type_face_beyond_its_base_s_reach_is_refused_naming_the_surface(tmp_path):
    """Domain: the base conic (R 25 mm, k -0.5) reaches 35.4 mm; a 40 mm semi-diameter is an error."""
    from lensmount.design.lens import load_lens

    path = _qed_file(tmp_path, {1: 0, 2: 1, 3: 40.0, 4: 0.01}, semi_diameter=40.0)
    with pytest.raises(InputError) as err:
        load_lens(path)
    assert "Q-type face of surface 1" in str(err.value) and "r = 35.36 mm" in str(err.value)


def test_lens_solid_follows_the_q_type_face():
    """The element's revolved profile (templates.lens_element) is sampled from the Q-type sag, not the
    base conic's: its optical segment lies on Profile.sag to rounding, and the conic is 0.1 mm away."""
    from lensmount.templates.lens_element import OpticalFace

    lens = read_zmx(ASL5040)
    face = OpticalFace.of(0, 0.0, lens.surfaces[0])
    seg = face.segment(22.86)
    r, z = np.array(seg.points).T
    assert seg.kind == "spline"
    assert np.max(np.abs(z - Profile.of(lens.surfaces[0]).sag(r * r))) < 1e-12
    assert np.max(np.abs(z - Profile(face.curvature, face.conic).sag(r * r))) > 0.1


def test_a_face_used_beyond_its_normalisation_radius_is_said_in_the_import_notes(tmp_path):
    from lensmount.optics.io.zemax import read_zmx_with_notes

    lens, notes = read_zmx_with_notes(_qed_file(tmp_path, {1: 1, 2: 1, 3: 4.0, 4: 0.001}, semi_diameter=5.0))
    said = [n.what for n in notes if n.where == "SURF 1" and "Q-type" in n.what]
    assert said and "beyond it (u up to 1.25)" in said[0] and "extrapolation" in said[0]
    assert np.isfinite(Profile.of(lens.surfaces[0]).sag(np.array([25.0]))).all()
