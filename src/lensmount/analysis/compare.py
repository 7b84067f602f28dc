"""Is the new design worse than the old one? A verdict that noise cannot turn into a regression.

Each run gives a value with a standard error (spread of independent passes) and,
for the bidirectional estimator, a bound on its remaining bias. The change
d = new − old has the standard error σ = √(σ_old² + σ_new²); with few passes the
error of σ itself matters, so the interval uses Student's t with the
Welch–Satterthwaite degrees of freedom. Bias bounds add linearly (they are
bounds, not random):

    d ± (t_{(1+c)/2, ν} · σ + b_old + b_new)

Against the tolerance T = tolerance · |old| (higher stray light is worse):
  - regression: the whole interval lies above T (exit 1);
  - no regression: the whole interval lies at or below T (an improvement when it lies below −T);
  - undecided: the interval straddles T — more photons decide it. The interval
    shrinks as 1/√photons, so both runs need f = (t·σ / (|d − T| − b))² times their
    photons; when the bias alone reaches |d − T|, no number of photons decides it.

Two runs of the same design differ only by noise; the interval then lies above T
with probability at most (1 − c)/2, so at c = 0.99 at most 0.5 % of such pairs read
"regression".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.stats import t as student_t

REGRESSION, NO_REGRESSION, IMPROVEMENT, UNDECIDED = "regression", "no regression", "improvement", "undecided"


@dataclass(frozen=True)
class Measurement:
    """A Monte Carlo figure: value, standard error (None = unknown, one pass), bias bound,
    and what it cost (passes, photons, seconds)."""

    value: float
    std_error: float | None
    bias_bound: float = 0.0
    passes: int = 2
    photons: int = 0
    time_s: float = 0.0


@dataclass(frozen=True)
class Verdict:
    """The comparison of one figure.

    change : new − old; relative_change : change / |old| (None when old is 0)
    low, high : the interval of the change at `confidence` (std errors and bias bounds)
    threshold : the tolerance in the figure's units (tolerance · |old|)
    more_photons, more_time_s : what would decide an undecided verdict (None otherwise or
        when more photons cannot: the bias bound alone spans the threshold)
    """

    verdict: str
    old: float
    new: float
    change: float
    relative_change: float | None
    low: float
    high: float
    threshold: float
    confidence: float
    more_photons: int | None = None
    more_time_s: float | None = None
    note: str = ""

    @property
    def regression(self) -> bool:
        return self.verdict == REGRESSION


def _welch_dof(a: Measurement, b: Measurement) -> float:
    terms = [(m.std_error ** 4) / max(m.passes - 1, 1) for m in (a, b) if m.std_error]
    var = sum(m.std_error ** 2 for m in (a, b) if m.std_error)
    if not terms or sum(terms) == 0:
        return math.inf
    return var * var / sum(terms)


def judge(old: Measurement, new: Measurement, tolerance: float = 0.05, confidence: float = 0.99) -> Verdict:
    """The verdict on new − old (see the module docstring). tolerance is relative to |old|."""
    if not 0 < confidence < 1:
        raise ValueError("confidence must lie in (0, 1)")
    change = new.value - old.value
    rel = change / abs(old.value) if old.value != 0 else None
    threshold = tolerance * abs(old.value)
    bias = (old.bias_bound or 0.0) + (new.bias_bound or 0.0)
    if old.std_error is None or new.std_error is None:
        return Verdict(UNDECIDED, old.value, new.value, change, rel, -math.inf, math.inf, threshold, confidence,
                       note="a run with a single pass has no error bar; run more passes")
    sigma = math.hypot(old.std_error, new.std_error)
    dof = _welch_dof(old, new)
    k = float(student_t.ppf(0.5 + confidence / 2, dof))  # the normal quantile when dof is infinite
    half = k * sigma + bias
    low, high = change - half, change + half
    if low > threshold:
        return Verdict(REGRESSION, old.value, new.value, change, rel, low, high, threshold, confidence)
    if high <= threshold:
        verdict = IMPROVEMENT if high < -threshold else NO_REGRESSION
        return Verdict(verdict, old.value, new.value, change, rel, low, high, threshold, confidence)
    margin = abs(change - threshold) - bias
    if margin <= 0 or sigma == 0:
        return Verdict(UNDECIDED, old.value, new.value, change, rel, low, high, threshold, confidence,
                       note="the bias bounds alone span the tolerance: more photons cannot decide this; "
                            "lower the bias (smaller radius, more passes) or widen the tolerance")
    factor = (k * sigma / margin) ** 2
    more = max(factor - 1.0, 0.0)
    return Verdict(UNDECIDED, old.value, new.value, change, rel, low, high, threshold, confidence,
                   more_photons=int(math.ceil(more * (old.photons + new.photons))),
                   more_time_s=more * (old.time_s + new.time_s),
                   note=f"about {factor:.1f}× the photons of both runs would decide it, if the change is as measured")


def parse_fraction(text: str, field: str) -> float:
    """'5%' or '0.05' → 0.05 (ValueError naming the field otherwise)."""
    s = str(text).strip()
    try:
        value = float(s[:-1]) / 100.0 if s.endswith("%") else float(s)
    except ValueError:
        raise ValueError(f"{field}: cannot read {text!r} as a fraction") from None
    if not math.isfinite(value):
        raise ValueError(f"{field}: {text!r} is not finite")
    return value


__all__ = ["Measurement", "Verdict", "judge", "parse_fraction", "REGRESSION", "NO_REGRESSION", "IMPROVEMENT",
           "UNDECIDED"]
