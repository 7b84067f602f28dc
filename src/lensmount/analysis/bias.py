"""The kernel (radius) bias of a progressive run, from a ladder of gather radii on the same photons.

Every pass also estimates its flux with every gather radius r taken as r·m for m in
`photon_gather.BIAS_LADDER` (same photons, same hit points): the curve F(ρ) near ρ = r. The pass's
kernel bias is b(r) = E[F(r)] − truth; what the ladder can say about it, and what it cannot:

- **The step outward.** D = F(2r) − F(r). For a bias c·ρ^k with k ≥ 1 (first order at a kink of the
  detector's importance, second order on smooth light) b(r) = D / (2^k − 1), at most D. The discs of
  2r hold 4× the photons and hit points of r, so D is far less noisy than the step inward to r/2 was
  (whose quarter of the photons made the old bound |2 D̄| + se as noisy as the estimate).
- **Its noise, counted once.** The interval the run reports is flux ± (2·se + bound). Write the
  flux as (F(r) − D) + D: the first term is unbiased for k = 1 and over-corrected for k > 1 (then
  |D| ≥ 3|b|), with its own standard error se* over the passes. |flux − truth| ≤ |D̄| + 2 se* whenever
  the corrected estimate's ±2 se* holds the truth, so the bound is |D̄| + 2·max(se* − se, 0): the
  step's noise enters in quadrature with the photons' (D shares them), not added to the whole error.
- **The model check.** c·ρ^k with k ≥ 1 fixes the shape of the ladder: its steps F(r) − F(r/√2),
  F(√2 r) − F(r), F(2r) − F(√2 r) are a, a·g, a·g² with g = 2^{k/2} ≥ √2, in each pass's own scale
  (`_shape_p`). A run gives no bound (`bounded = False`, and why) when (a) the steps are significantly
  not of that shape (one-sided: a curve steepening outward only makes D larger than the bias), (b)
  the first outward step is measured and the second barely grows on it (g ≤ MIN_GROWTH; below √2
  the bound is widened by 1/(g² − 1) instead, `_flattening`), or (c) the estimate moves by more than
  MAX_STEP between r and 2r (a bias of the order of the value). That is light concentrated on a
  feature far smaller than r inside a narrow seen window (F ∝ 1/ρ: the estimate diluted by the disc),
  two orders of opposite sign, a disc wider than its face: `compare` and the
  stopping rule take such a run's error as unknown, not as zero.

A gather that loses photons on its wider discs flattens the curve the same way: 19 % of default case-1
runs could not bound their bias while grazing photons on the curved diaphragm bore were dropped by a
test of their world direction (`photon_gather.turned` keeps them; CHANGELOG.md, "Case 1's runs that could not bound their bias").

What no ladder of radii ≥ r/√2 can see is a bias that appears only below r/√2 and is flat above it;
the radius caps (`radius.radius_caps`: r_0 below the face's half width and its bend's chord) are
what keep a disc from spanning a whole face, where that would happen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lensmount.integrators.photon_mapping.photon_gather import BIAS_LADDER

SHAPE_P = 0.1  # a ladder whose shape the model c·ρ^k, k ≥ 1, explains with p below this: no bound
SQRT2 = math.sqrt(2.0)  # the ratio of successive √2 steps at k = 1; steeper curves have more
SLOPE_T = 2.0  # the first outward step counts as measured (its ratio to the next one means something) beyond this t
# A run whose estimate moves by more than this share between r and 2r has a bias of the order of itself:
# the slit scene's runs (a 0.02 mm spot under a 5 mm disc) moved by 40-60 % with steps too noisy in 4
# passes to show the curve flattening, and their bounds missed a bias of −0.6 to −0.8.
MAX_STEP = 0.2
MIN_GROWTH = 1.1  # outward steps growing by less than this per √2 (k < 0.28): the bias at r has no bound
_RUNG = {m: i for i, m in enumerate(BIAS_LADDER)}
_INNER, _R, _MID, _OUTER = (_RUNG[math.sqrt(0.5)], _RUNG[1.0], _RUNG[math.sqrt(2.0)], _RUNG[2.0])


@dataclass
class BiasBound:
    """The kernel bias of a run's mean (one figure: the total, or one part), mm².

    bound : what the run's interval needs beyond ±2 standard errors to hold the bias (|D̄| + 2·max(se* −
        se, 0), module docstring); inf when unknown (too few passes), None when `bounded` is False
    step : D̄, the mean outward step F(2r) − F(r) (the bias itself for a first-order bias, 3× it at second),
        times the flattening factor when one applies
    bounded : False when the ladder says the bias is not c·ρ^k with k ≥ 1 (then no bound is honest)
    reason : why not, in the optics engineer's words ("" when bounded)
    shape_p : p-value of the model check (1 when it was not made: no density estimate, too few passes)
    """

    bound: float | None
    step: float = 0.0
    bounded: bool = True
    reason: str = ""
    shape_p: float = 1.0


def ladder_bias(flux: np.ndarray, ladder: np.ndarray, t_factor) -> BiasBound:
    """The bias of the mean of `flux` (n,) from each pass's ladder (n, L) (`BIAS_LADDER`), n ≥ 3; passes
    without a density estimate carry their flux on every rung (no bias). `t_factor(n)` widens a standard
    error of n passes to Student's t."""
    n = len(flux)
    flux, ladder = np.asarray(flux, np.float64), np.asarray(ladder, np.float64)
    steps = np.diff(ladder[:, [_INNER, _R, _MID, _OUTER]], axis=1)  # (n, 3): inward, first and second outward
    if not np.any(steps):
        return BiasBound(0.0)
    d = ladder[:, _OUTER] - ladder[:, _R]
    # The shape in each pass's own scale: passes whose few hit points near the light make one pass 3× the
    # next carry steps in proportion, and the spread of the raw steps hid a curve the same in every pass.
    outer = ladder[:, _OUTER]
    steps = steps / outer[:, None] if np.all(outer > 0) else steps
    p = _shape_p(steps)
    if p < SHAPE_P:
        return BiasBound(None, float(ladder[:, _OUTER].mean() - ladder[:, _R].mean()), False,
                         _why_not(steps), p)
    at_r = abs(float(ladder[:, _R].mean()))
    if abs(d.mean()) > MAX_STEP * at_r:
        return BiasBound(None, float(d.mean()), False,
                         f"the estimate changes {_share(abs(d.mean()), at_r)} when the gather radius doubles: "
                         "the radius is not small against the light's structure (a lit feature far smaller than the "
                         "radius, or a seen window narrower than it), and no power of the radius can be trusted to "
                         "extrapolate that far; more passes (the radius shrinks) or a smaller radius (--neighbours)", p)
    factor = _flattening(steps)
    if factor is None:
        return BiasBound(None, float(d.mean()), False, _why_not(steps), p)
    d = factor * d
    widen = t_factor(n) / math.sqrt(n)
    se, se_corrected = np.std(flux, ddof=1) * widen, np.std(flux - d, ddof=1) * widen
    return BiasBound(float(abs(d.mean()) + 2.0 * max(se_corrected - se, 0.0)), float(d.mean()), True, "", p)


def _share(change: float, value: float) -> str:
    """'by 35 %', or 'from zero' when the value at r is 0 (no division by it)."""
    return f"by {100 * change / value:.0f} %" if value > 0 else "from zero"


def _flattening(steps: np.ndarray) -> float | None:
    """How much more than the outward step F(2r) − F(r) the bias at r can be, from the ladder's own
    curvature: 1 unless the first outward step is clearly there (SLOPE_T standard errors) and the second
    is less than √2 times it (the curve flattens outward, as k < 1 would, or as two orders of opposite
    sign do on their way to cancelling). Then the steps inward are taken to shrink by the observed ratio
    ĝ = Δ̄2 / Δ̄1 per √2 (a geometric series: b(r) = Δ1 / (ĝ − 1), = the outward step D = Δ1 (1 + ĝ) times
    1 / (ĝ² − 1)); None when ĝ ≤ MIN_GROWTH: the series does not converge (no bound).

    Why: the one-sided shape test rejects only what is significant, and a curve that flattens by a margin
    within its noise went through it with a bound that missed the bias (two orders of opposite sign: 88 %
    of runs held the truth; a lit spot under a wide disc in a planar scene: 59 %)."""
    n = len(steps)
    d1, d2 = steps[:, 1].mean(), steps[:, 2].mean()
    spread = float(np.std(steps[:, 1], ddof=1))
    if not abs(d1) > SLOPE_T * spread / math.sqrt(n):
        return 1.0
    growth = d2 / d1
    if growth >= SQRT2:
        return 1.0
    if growth <= MIN_GROWTH:
        return None
    return 1.0 / (growth * growth - 1.0)


def _shape_p(steps: np.ndarray) -> float:
    """p-value that the steps (n, 3) (inward Δ0, outward Δ1, Δ2) are those of a bias c·ρ^k with k ≥ 1:
    a, a·g, a·g² with g ≥ √2 and a of one sign s, i.e. s·Δ0 ≥ 0, s·Δ1 ≥ 0, s·(Δ1 − √2 Δ0) ≥ 0 and
    s·(Δ2 − √2 Δ1) ≥ 0. Each constraint gets a one-sided t-test over the passes (Bonferroni over the
    four); the model is rejected only when it is rejected for both signs. Why one-sided: a curve that
    steepens outward (k > 2) only makes the outward step larger than the bias, which is safe; what
    makes it miss is a curve that flattens outward or turns (dilution, orders of opposite sign)."""
    from scipy.stats import t as student

    n = len(steps)
    d0, d1, d2 = steps.T
    constraints = (d0, d1, d1 - SQRT2 * d0, d2 - SQRT2 * d1)
    p_sign = []
    for sign in (1.0, -1.0):
        ps = []
        for series in constraints:
            m, sd = sign * float(series.mean()), float(np.std(series, ddof=1))
            ps.append((1.0 if m >= 0 else 0.0) if not sd > 0 else float(student.cdf(m / (sd / math.sqrt(n)), n - 1)))
        p_sign.append(min(1.0, len(constraints) * min(ps)))
    return max(p_sign)


def _why_not(steps: np.ndarray) -> str:
    """The ladder's shape in words: the run's flux against its gather radius."""
    a, b, c = steps.mean(axis=0)
    if np.sign(a) != np.sign(b) or np.sign(b) != np.sign(c):
        return ("the estimate rises and falls with the gather radius between r/√2 and 2r (bias orders of "
                "opposite sign, or a disc wider than its face): the bias at r cannot be bounded from the ladder")
    if abs(c) < math.sqrt(2.0) * abs(b):
        return ("the estimate changes less and less as the gather radius grows (like 1/r or slower: light on a "
                "feature far smaller than the radius, diluted by the disc): the bias at r cannot be bounded from "
                "the ladder; a smaller radius (--neighbours) or more photons per pass")
    return ("the estimate changes with the gather radius faster than r² between r and 2r: the bias at r cannot "
            "be bounded from the ladder")


__all__ = ["BiasBound", "ladder_bias", "SHAPE_P"]
