"""Test machinery for BSDFs, written independently of the models' own sampling code.

- `incidence(deg, n)`: wi at a polar angle in the x–z plane over n = +z.
- `independent_albedo`: ∫ f cosθo dωo by Monte Carlo with a defensive mixture
  (cosine hemisphere + uniform cap around the mirror direction), never the model's sampler.
- `chi2_test`: pbrt/Mitsuba-style goodness of fit of `sample` against `pdf`
  integrated over bins, with bins in the equal-area (chord, φ) coordinates around
  the mirror direction, so narrow lobes are resolved; the dead lanes make one more bin.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

Z = np.array([0.0, 0.0, 1.0])


def incidence(deg: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """wi (count, 3) at polar angle `deg` from n = +z, in the x–z plane; n (count, 3)."""
    t = math.radians(deg)
    wi = np.tile([math.sin(t), 0.0, math.cos(t)], (count, 1))
    return wi, np.tile(Z, (count, 1))


def mirror_of(wi: np.ndarray, n: np.ndarray) -> np.ndarray:
    return 2.0 * np.sum(wi * n, axis=1, keepdims=True) * n - wi


def lobe_axes(r: np.ndarray, n: np.ndarray):
    """Orthonormal (e1, e2) ⊥ r (each (N,3)): e1 toward the normal's side, e2 = r × e1 (a fixed frame at r = n)."""
    e1 = n - np.sum(n * r, axis=1, keepdims=True) * r
    norm = np.linalg.norm(e1, axis=1, keepdims=True)
    fallback = np.cross(r, np.array([0.0, 1.0, 0.0]))
    e1 = np.where(norm > 1e-9, e1 / np.maximum(norm, 1e-300), fallback / np.linalg.norm(fallback, axis=1, keepdims=True))
    e2 = np.cross(r, e1)
    return e1, e2


def from_chord(r, e1, e2, s, phi):
    """Direction at chord distance s = |w − r| = 2 sin(θ/2) and azimuth phi around r (equal-area: dω = s ds dφ)."""
    x = 0.5 * s * s
    cos_t = 1.0 - x
    sin_t = np.sqrt(np.maximum(x * (2.0 - x), 0.0))
    w = cos_t[:, None] * r + (sin_t * np.cos(phi))[:, None] * e1 + (sin_t * np.sin(phi))[:, None] * e2
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def to_chord(w, r, e1, e2):
    s = np.linalg.norm(w - r, axis=1)
    phi = np.mod(np.arctan2(np.sum(w * e2, axis=1), np.sum(w * e1, axis=1)), 2.0 * math.pi)
    return s, phi


def cap_chords(bsdf, deg: float) -> list[float]:
    """Chord radii of the uniform caps around r used by `independent_albedo`: the lobe's core
    (1.5 and 6 half-widths) and the 6-half-width cap stretched by 1/cosθi (direction-cosine
    lobes widen toward grazing); the whole sphere (2) for broad lobes."""
    hw = bsdf.lobe_half_width_deg
    if not math.isfinite(hw) or hw <= 0:
        return [2.0]
    s_h = 2.0 * math.sin(math.radians(hw) / 2.0)
    stretch = 1.0 / max(math.cos(math.radians(deg)), 0.05)
    return [min(2.0, 1.5 * s_h), min(2.0, 6.0 * s_h), min(2.0, 6.0 * s_h * stretch)]


def independent_albedo(bsdf, deg: float, count: int, rng: np.random.Generator) -> tuple[float, float]:
    """(estimate, standard error) of ∫ f cosθo dωo at incidence `deg`, by importance sampling a fixed
    mixture q (equal weights) of the cosine hemisphere and uniform caps |w − r| < s around the mirror
    direction r (`cap_chords`). A cap is equal-area in the chord s: solid angle π s², density 1/(π s²)."""
    wi, n = incidence(deg, count)
    r = mirror_of(wi, n)
    e1, e2 = lobe_axes(r, n)
    caps = np.array(cap_chords(bsdf, deg))
    pick = rng.integers(0, len(caps) + 1, count)  # 0: cosine hemisphere, k: cap k-1
    u = rng.random((count, 2))
    rad = np.sqrt(u[:, 0])
    phi = 2.0 * math.pi * u[:, 1]
    w_cos = np.stack([rad * np.cos(phi), rad * np.sin(phi), np.sqrt(1.0 - u[:, 0])], axis=1)
    radius = caps[np.maximum(pick - 1, 0)]
    w_cap = from_chord(r, e1, e2, radius * rad, phi)
    wo = np.where((pick == 0)[:, None], w_cos, w_cap)
    cos_o = wo[:, 2]
    chord = np.linalg.norm(wo - r, axis=1)
    q = np.maximum(cos_o, 0.0) / math.pi
    for s_cap in caps:
        q = q + (chord < s_cap) / (math.pi * s_cap**2)
    q /= len(caps) + 1
    f = bsdf.eval(wi, wo, n)
    value = np.where((cos_o > 0) & (q > 0), f * np.maximum(cos_o, 0.0) / np.where(q > 0, q, 1.0), 0.0)
    return float(value.mean()), float(value.std(ddof=1) / math.sqrt(count))


def chord_edges(bsdf, bins: int) -> np.ndarray:
    """Radial (chord) bin edges around the mirror direction: geometric from the lobe's core, or equal-area for broad lobes."""
    hw = bsdf.lobe_half_width_deg
    if math.isfinite(hw) and hw < 20.0:
        s_h = 2.0 * math.sin(math.radians(hw) / 2.0)
        return np.concatenate([[0.0], np.geomspace(0.25 * s_h, 2.0, bins)])
    return np.sqrt(np.linspace(0.0, 4.0, bins + 1))


def _cell_nodes(lo, hi, cells: int, order: int):
    """Gauss–Legendre nodes/weights of `cells` equal cells in each interval [lo_i, hi_i]: (M, cells·order) each."""
    x, w = np.polynomial.legendre.leggauss(order)
    t = ((np.arange(cells)[:, None] + 0.5 * (x[None, :] + 1.0)) / cells).ravel()
    wt = np.tile(0.5 * w / cells, cells)
    return lo[:, None] + (hi - lo)[:, None] * t[None, :], (hi - lo)[:, None] * wt[None, :]


def _integrate_cells(bsdf, wi1, n1, r, e1, e2, s_lo, s_hi, p_lo, p_hi, cells, order):
    """∫ pdf dω over each rectangle [s_lo, s_hi] × [p_lo, p_hi] (arrays (M,)), as (M, cells², order²) pieces
    summed per sub-cell -> (M, cells*cells) contributions and a flag per sub-cell: pdf both zero and non-zero in it."""
    s, ws = _cell_nodes(s_lo, s_hi, cells, order)  # (M, C·O)
    ph, wp = _cell_nodes(p_lo, p_hi, cells, order)
    m, k = s.shape
    ss = np.repeat(s[:, :, None], k, 2)            # (M, k_s, k_p)
    pp = np.repeat(ph[:, None, :], k, 1)
    ww = ws[:, :, None] * wp[:, None, :] * ss       # dω = s ds dφ
    count = ss.size
    dirs = from_chord(np.repeat(r, count, 0), np.repeat(e1, count, 0), np.repeat(e2, count, 0), ss.ravel(), pp.ravel())
    pdf = bsdf.pdf(np.repeat(wi1, count, 0), dirs, np.repeat(n1, count, 0)).reshape(ss.shape)
    piece = (pdf * ww).reshape(m, cells, order, cells, order)
    zero = (pdf == 0).reshape(piece.shape).any(axis=(2, 4))
    nonzero = (pdf != 0).reshape(piece.shape).any(axis=(2, 4))
    return piece.sum(axis=(2, 4)).reshape(m, -1), (zero & nonzero).reshape(m, -1)


def expected_fractions(bsdf, wi1, n1, s_edges, phi_bins: int, cells: int = 8, order: int = 4) -> np.ndarray:
    """∫ pdf dω over each (s, φ) bin, (len(s_edges)-1, phi_bins): Gauss–Legendre on cells×cells sub-cells
    per bin; sub-cells that straddle the edge of the pdf's support (the horizon) are integrated again on a
    16×16 finer grid, since the pdf jumps or kinks there."""
    r = mirror_of(wi1, n1)
    e1, e2 = lobe_axes(r, n1)
    phi_edges = np.linspace(0.0, 2.0 * math.pi, phi_bins + 1)
    si, pj = np.meshgrid(np.arange(len(s_edges) - 1), np.arange(phi_bins), indexing="ij")
    si, pj = si.ravel(), pj.ravel()
    s_lo, s_hi, p_lo, p_hi = s_edges[si], s_edges[si + 1], phi_edges[pj], phi_edges[pj + 1]
    part, mixed = _integrate_cells(bsdf, wi1, n1, r, e1, e2, s_lo, s_hi, p_lo, p_hi, cells, order)
    b, c = np.nonzero(mixed)
    if len(b):
        ds, dp = (s_hi - s_lo)[b] / cells, (p_hi - p_lo)[b] / cells
        c_s, c_p = c // cells, c % cells
        sub_lo, sub_plo = s_lo[b] + c_s * ds, p_lo[b] + c_p * dp
        fine, _ = _integrate_cells(bsdf, wi1, n1, r, e1, e2, sub_lo, sub_lo + ds, sub_plo, sub_plo + dp, 16, order)
        part[b, c] = fine.sum(axis=1)
    return part.sum(axis=1).reshape(len(s_edges) - 1, phi_bins)


def chi2_test(bsdf, deg: float, count: int, rng: np.random.Generator, s_bins: int = 16, phi_bins: int = 12):
    """p-value of sample() against pdf() at incidence `deg`; also returns the statistic and dof."""
    wi, n = incidence(deg, count)
    wo, weight, pdf = bsdf.sample(wi, n, rng.random((count, 2)))
    live = weight > 0
    assert np.array_equal(live, pdf > 0), "a lane is live in weight but not in pdf (or the reverse)"
    s_edges = chord_edges(bsdf, s_bins)
    r = mirror_of(wi[:1], n[:1])
    e1, e2 = lobe_axes(r, n[:1])
    s, phi = to_chord(wo[live], r, e1, e2)
    observed, _, _ = np.histogram2d(s, phi, bins=[s_edges, np.linspace(0, 2 * math.pi, phi_bins + 1)])
    frac = expected_fractions(bsdf, wi[:1], n[:1], s_edges, phi_bins)
    obs = np.append(observed.ravel(), count - live.sum())
    exp = np.append(frac.ravel() * count, max(count * (1.0 - frac.sum()), 0.0))
    # Pool sparse bins (expected < 5) into one, as Mitsuba's chi2 does.
    order = np.argsort(exp)
    obs, exp = obs[order], exp[order]
    sparse = exp < 5.0
    pooled_obs = [obs[sparse].sum()] if sparse.any() else []
    pooled_exp = [exp[sparse].sum()] if sparse.any() else []
    obs = np.concatenate([pooled_obs, obs[~sparse]])
    exp = np.concatenate([pooled_exp, exp[~sparse]])
    if len(exp) and exp[0] < 5.0:  # a pooled bin still too sparse: its count must be small too
        assert obs[0] <= 10, f"{obs[0]} samples where pdf integrates to {exp[0]:.2f}"
        obs, exp = obs[1:], exp[1:]
    stat = float(np.sum((obs - exp) ** 2 / exp))
    dof = len(exp) - 1
    return float(stats.chi2.sf(stat, dof)), stat, dof
