"""Is the new design worse than the old one? A verdict that noise cannot turn into a regression.

Each run gives a value with a standard error and, for the bidirectional estimator, a bound on
its remaining bias. The summaries' standard errors are already Student-t widened for their own
passes (`analysis.error_bar.t_factor`: ±2 of them cover 95 %); the comparison takes the plain
ones back (÷ t_factor(passes)) and widens once, with its own quantile. The change
d = new − old has the standard error σ = √(σ_old² + σ_new²), Student's t with the
Welch–Satterthwaite degrees of freedom; bias bounds add linearly (they are bounds, not random):

    d ± (t_{(1+c)/2, ν} · σ + b_old + b_new)

A figure that read exactly zero in every pass has no spread to measure: it enters as the
interval [0, U], U its no-signal bound (`Accumulator.no_signal_bound`, a Poisson bound on
photons never seen) taken at the comparison's confidence, never as 0 ± 0. The other run's
t-interval and U then share each side's (1 − c)/2 (Bonferroni), so "regression" against an
all-zero old run needs the new run's lower end above the old run's bound.

Against the tolerance T = tolerance · |old| (higher stray light is worse):
  - regression: the whole interval lies above T (exit 1);
  - no regression: the whole interval lies at or below T (an improvement when it lies below −T);
  - undecided: the interval straddles T. What would decide it (`to_decide`): the fewest more
    passes of either run, weighted by what a pass of each costs, after which the projected
    interval (standard errors ∝ 1/√passes, Student's t at the larger degrees of freedom, no-signal
    bounds ∝ 1/passes, the change as measured) clears T. When the bias alone reaches |d − T|,
    no number of photons decides it.

Two runs of the same design differ only by noise; the interval then lies above T with
probability at most (1 − c)/2, so at c = 0.99 at most 0.5 % of such pairs read "regression".
Looking again after more passes spends that error again: `look_confidence` gives look j the
share α · 6 / (π² j²) of α = 1 − c, which sums to α over any number of looks, so a loop that
resumes the runs until a verdict (`loop.compare`, --until-decided) keeps its error rate at c.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from scipy.special import stdtrit

from lensmount.analysis.error_bar import t_factor
from lensmount.analysis.passes import ZERO_SIGNAL_COUNT

REGRESSION, NO_REGRESSION, IMPROVEMENT, UNDECIDED = "regression", "no regression", "improvement", "undecided"
_MAX_MORE_PASSES = 2 ** 30  # beyond this "more photons" is no answer


@dataclass(frozen=True)
class Measurement:
    """A Monte Carlo figure: value, standard error as the summaries give it (the passes' spread,
    Student-t widened by `error_bar.t_factor`; None = unknown, fewer than 3 passes), bias bound,
    what it cost (passes, photons, seconds), and the 95 % no-signal bound: what the figure lies
    below when it read exactly zero in every pass (None: not known; a zero then decides nothing).
    bias_unbounded : why the run could not bound its kernel bias (`analysis.bias`; None: bounded): its
    error is then unknown and nothing is decided on it."""

    value: float
    std_error: float | None
    bias_bound: float = 0.0
    passes: int = 2
    photons: int = 0
    time_s: float = 0.0
    no_signal_bound: float | None = None
    bias_unbounded: str | None = None

    @property
    def no_signal(self) -> bool:
        """Every pass read exactly zero: no spread, only a bound."""
        return self.value == 0 and self.std_error == 0

    @property
    def plain_error(self) -> float:
        """The passes' standard deviation over √passes, without the summaries' t widening."""
        return self.std_error / t_factor(self.passes)

    def bound(self, tail: float) -> float:
        """The no-signal bound that fails with probability `tail` (Poisson: −ln tail photons' worth)."""
        if self.no_signal_bound is None:
            return math.inf
        return self.no_signal_bound * -math.log(tail) / ZERO_SIGNAL_COUNT

    def with_more_passes(self, more: int) -> "Measurement":
        """The same run projected to `more` further passes: same value, spread ∝ 1/√passes, no-signal
        bound ∝ 1/passes, photons and time in proportion."""
        if more <= 0:
            return self
        n = self.passes + more
        se = None if self.std_error is None else self.plain_error * math.sqrt(self.passes / n) * t_factor(n)
        bound = None if self.no_signal_bound is None else self.no_signal_bound * self.passes / n
        return replace(self, std_error=se, passes=n, photons=round(self.photons * n / self.passes),
                       time_s=self.time_s * n / self.passes, no_signal_bound=bound)


@dataclass(frozen=True)
class Verdict:
    """The comparison of one figure.

    change : new − old; relative_change : change / |old| (None when old is 0)
    low, high : the interval of the change at `confidence` (std errors, bias and no-signal bounds)
    threshold : the tolerance in the figure's units (tolerance · |old|)
    more_passes : (old, new) further passes that would decide an undecided verdict, if the change is
        as measured; more_photons, more_time_s : what they cost (None otherwise, or when more
        photons cannot decide: the bias bound alone spans the threshold)
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
    more_passes: tuple[int, int] | None = None

    @property
    def regression(self) -> bool:
        return self.verdict == REGRESSION


def _welch_dof(a: Measurement, b: Measurement) -> float:
    errors = [(m.plain_error, m.passes) for m in (a, b) if m.std_error]
    terms = [e ** 4 / max(n - 1, 1) for e, n in errors]
    var = sum(e * e for e, _ in errors)
    if not terms or sum(terms) == 0:
        return math.inf
    return var * var / sum(terms)


def _t(tail: float, dof: float) -> float:
    return float(stdtrit(dof, 1.0 - tail))  # Student's t quantile (the normal's when dof is infinite)


def _ends(m: Measurement, tail_low: float, tail_high: float) -> tuple[float, float]:
    """One run's own interval of its true value, failing below with probability tail_low, above
    with tail_high: [0, U] for no signal, else the t-interval plus the bias bound."""
    if m.no_signal:
        return 0.0, m.bound(tail_high)
    dof = max(m.passes - 1, 1)
    return (m.value - _t(tail_low, dof) * m.plain_error - m.bias_bound,
            m.value + _t(tail_high, dof) * m.plain_error + m.bias_bound)


def interval(old: Measurement, new: Measurement, confidence: float) -> tuple[float, float]:
    """The interval of new − old at `confidence` (module docstring); both std errors known."""
    side = (1.0 - confidence) / 2
    if not (old.no_signal or new.no_signal):
        change = new.value - old.value
        sigma = math.hypot(old.plain_error, new.plain_error)
        half = _t(side, _welch_dof(old, new)) * sigma + old.bias_bound + new.bias_bound
        return change - half, change + half
    # Low end: new's lower end (random unless new has no signal: its 0 is sure) minus old's upper.
    low_tail = side / (1 if new.no_signal else 2)
    # High end: new's upper end minus old's lower end (random unless old has no signal).
    high_tail = side / (1 if old.no_signal else 2)
    new_low, new_high = _ends(new, low_tail, high_tail)
    old_low, old_high = _ends(old, high_tail, low_tail)
    return new_low - old_high, new_high - old_low


def _decides(low: float, high: float, threshold: float, above: bool) -> bool:
    return low > threshold if above else high <= threshold


def to_decide(old: Measurement, new: Measurement, threshold: float, confidence: float,
              grows: tuple[bool, bool] = (True, True)) -> tuple[int, int] | None:
    """(old, new) further passes after which the interval would clear `threshold` on the side the
    change lies (module docstring), cheapest by each run's time (else photons) per pass; None when
    no number of passes would (the bias bounds alone reach the threshold, or the change is on it).
    grows : which runs may take more passes (a stored run of an earlier revision cannot)."""
    if old.bias_unbounded or new.bias_unbounded or not (math.isfinite(old.std_error) and math.isfinite(new.std_error)):
        return None  # the error is unknown, not small: no number of passes can be promised
    above = new.value - old.value > threshold
    cost = [(m.time_s or m.photons or 1.0) / max(m.passes, 1) for m in (old, new)]

    def decided(a_old: int, a_new: int) -> bool:
        return _decides(*interval(old.with_more_passes(a_old), new.with_more_passes(a_new), confidence),
                        threshold, above)

    if decided(0, 0):
        return 0, 0
    # Three ways to grow: each run alone, or both towards passes ∝ (spread per pass)/√(cost per pass),
    # the split that minimises cost at a given σ (a no-signal run's spread taken as its bound's).
    spread = [(m.bound(0.05) if m.no_signal else m.plain_error) * math.sqrt(m.passes) for m in (old, new)]
    weight = [x / math.sqrt(c) for x, c in zip(spread, cost)]
    share = [w / sum(weight) if sum(weight) > 0 else 0.5 for w in weight]
    ways = {"old": lambda k: (k, 0), "new": lambda k: (0, k),
            "both": lambda k: tuple(max(math.ceil(k * f) - m.passes, 0) for f, m in zip(share, (old, new)))}
    if not grows[0]:
        ways.pop("old"), ways.pop("both")
    if not grows[1]:
        ways.pop("new"), ways.pop("both", None)
    best = None
    for split in ways.values():
        hi = 1
        while not decided(*split(hi)):
            hi *= 2
            if hi > _MAX_MORE_PASSES:
                break
        else:
            lo = hi // 2  # not decided at lo (or lo = 0), decided at hi
            while hi - lo > 1:
                mid = (lo + hi) // 2
                lo, hi = (lo, mid) if decided(*split(mid)) else (mid, hi)
            a = split(hi)
            if best is None or a[0] * cost[0] + a[1] * cost[1] < best[0] * cost[0] + best[1] * cost[1]:
                best = a
    return best


def judge(old: Measurement, new: Measurement, tolerance: float = 0.05, confidence: float = 0.99) -> Verdict:
    """The verdict on new − old (see the module docstring). tolerance is relative to |old|."""
    if not 0 < confidence < 1:
        raise ValueError("confidence must lie in (0, 1)")
    change = new.value - old.value
    rel = change / abs(old.value) if old.value != 0 else None
    threshold = tolerance * abs(old.value)
    if old.std_error is None or new.std_error is None:
        return Verdict(UNDECIDED, old.value, new.value, change, rel, -math.inf, math.inf, threshold, confidence,
                       note="a run with fewer than 3 passes has no error bar; run more passes")
    unbounded = [f"the {name} run cannot bound its kernel bias ({m.bias_unbounded})"
                 for name, m in (("old", old), ("new", new)) if m.bias_unbounded]
    unbounded += [f"the {name} run's passes sum terms too heavy-tailed for an error bar (a few photons carry the "
                  "run; `simulate` warns which)" for name, m in (("old", old), ("new", new))
                  if not math.isfinite(m.std_error)]
    if unbounded:
        return Verdict(UNDECIDED, old.value, new.value, change, rel, -math.inf, math.inf, threshold, confidence,
                       note="; ".join(unbounded) + ": its error is unknown, so nothing is decided on it")
    low, high = interval(old, new, confidence)
    if low > threshold:
        return Verdict(REGRESSION, old.value, new.value, change, rel, low, high, threshold, confidence)
    if high <= threshold:
        verdict = IMPROVEMENT if high < -threshold else NO_REGRESSION
        return Verdict(verdict, old.value, new.value, change, rel, low, high, threshold, confidence)
    zero = " and ".join(f"the {name} run read no signal (below {m.bound((1 - confidence) / 2):.2g})"
                        for name, m in (("old", old), ("new", new)) if m.no_signal)
    zero = f"{zero}; " if zero else ""
    if any(m.no_signal and m.no_signal_bound is None for m in (old, new)):
        return Verdict(UNDECIDED, old.value, new.value, change, rel, low, high, threshold, confidence,
                       note="a run read no signal and its summary gives no bound for it (an older lensmount's "
                            "run): simulate it again")
    more = to_decide(old, new, threshold, confidence)
    if more is None:
        return Verdict(UNDECIDED, old.value, new.value, change, rel, low, high, threshold, confidence,
                       note=zero + "the bias bounds (or a change right at the tolerance) keep the interval on both "
                            "sides however many photons: lower the bias (smaller radius, more passes) or widen "
                            "the tolerance")
    photons = sum(round(a * m.photons / max(m.passes, 1)) for a, m in zip(more, (old, new)))
    seconds = sum(a * m.time_s / max(m.passes, 1) for a, m in zip(more, (old, new)))
    runs = " and ".join(f"{a} more pass{'es' if a != 1 else ''} of the {name} run"
                        for a, name in zip(more, ("old", "new")) if a)
    return Verdict(UNDECIDED, old.value, new.value, change, rel, low, high, threshold, confidence,
                   more_photons=photons, more_time_s=seconds, more_passes=more,
                   note=f"{zero}about {runs} would decide it, if the change is as measured")


def look_confidence(confidence: float, look: int) -> float:
    """The confidence of look `look` (1, 2, …) of a sequence that keeps its overall error at
    1 − confidence: look j spends α · 6 / (π² j²) of α (Σ over all j is α)."""
    return 1.0 - (1.0 - confidence) * 6.0 / (math.pi ** 2 * look * look)


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


__all__ = ["Measurement", "Verdict", "interval", "judge", "look_confidence", "to_decide", "parse_fraction", "REGRESSION", "NO_REGRESSION", "IMPROVEMENT",
           "UNDECIDED"]
