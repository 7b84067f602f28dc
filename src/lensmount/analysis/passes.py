"""Accumulator: the run's answer from independent passes (mean, batch-means error, drift).

Every pass of an integrator is a complete, independent estimate Ê_i (see
`/work/shared/reference/bidirectional-estimator.md`). The run's answer is the plain
mean of the passes and its standard error is the sample standard deviation of the
Ê_i over √n — per pixel and for the total flux. The state is nothing but sums
(n, Σ Ê_i, Σ Ê_i²) plus the per-pass totals, so it is also the checkpoint: merging
passes in pass order gives bit-identical numbers on one worker or many.

The progressive radius still shrinks from pass to pass, so the mean of Ê_i drifts
(the density-estimation bias). `drift()` compares the first half of the passes with
the second half; a drift well beyond its own error bar says "run more passes".

What the error bar includes (docs/bidirectional.md, "What the error bar includes"):

- the standard error is the passes' spread, widened for few passes by Student's t
  (`t_factor`: ±2 standard errors cover 95 % for normal passes at any n) and unknown
  (inf, null in the summary) below `MIN_PASSES`;
- the kernel bias is NOT in it. `bias_bound()` estimates it from every pass's own
  estimates on a ladder of gather radii (`PassEstimate.part_flux_ladder`, `analysis.bias`): the
  step outward F(2r) − F(r) bounds a bias c·r^k, k ∈ [1, 2], its noise counted in quadrature
  with the passes' spread; a ladder whose shape is not that model gives no bound (`BiasBound`);
- a run whose passes are all exactly zero has no error bar: `upper_bound()` gives the
  95 % bound from the photons traced (none of them reached the detector, and none carried
  more than the heaviest emitted weight); `no_signal_bound()` is the same bound for any part
  that read zero;
- the spread of the passes is an error bar only while no single pass dominates them. `tail()`
  tests the largest pass against the others (Grubbs's outlier test, one-sided, and at least
  TAIL_RATIO medians): a rare event
  that makes one pass several times the rest (one pass in 432 at 4.4× the median on
  case 1) inflates the spread and moves the mean by more than the quoted error says, and runs
  that have not met it yet read low with a small error. Such a run is flagged `heavy`, names the
  path that carried the excess, and does not count as converged (`converged`);
- nor is it while the terms a pass sums are heavy-tailed. A pass is a sum over many
  photons (and photon × hit-point pairs); every pass keeps its LARGEST largest terms
  (`PassEstimate.largest`), and Hill's estimate over the run's TAIL_K largest (`tail_index`) gives the
  tail's index α (P(term > x) ∝ x^−α): the terms show it in every pass, long before one pass is large
  enough to stand out, and in the runs that would stop early reading low. α < LIGHT_TAIL: the error bar
  widens by the tail allowance (`Tail.allowance`), what a run that has not met its tail yet typically
  misses (in `flux_std_error`, so in every interval quoted from it); α ≤ UNBOUNDED_TAIL: that is
  unbounded, the run has no error bar (relative error unknown: no stop on a target);
- unless the estimator states what bounds a term (`PassEstimate.term_bound`: a forward photon's flux is at most
  its emitted flux times its finishes' weights). A pass is then a sum of independent terms in [0, B]: its
  variance is finite (at most B times its mean), so the spread of the passes is the central limit's error bar
  and no power law is fitted to the terms (whose few sizes, one bounce and two, are weight classes, not a
  tail); the allowance is one term at the bound the run may not have met, B/n (0 once a term within CLASS_GAP of
  B has been met: the heaviest class is then in the spread). The largest pass is tested
  against what sums of such terms can do (`bounded_outlier_p`: Bennett's inequality, the Poisson skew of a few
  heavy terms a pass, Šidák over the n passes), not against normal passes.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lensmount.analysis.bias import BiasBound, ladder_bias
from lensmount.analysis.error_bar import MIN_PASSES, t_factor
from lensmount.analysis.paths import PathSums
from lensmount.atomic import NPZ_DAMAGE, write_npz
from lensmount.errors import InputError
from lensmount.integrators.estimate import AIMED_PASSES, LARGEST, PassEstimate
from lensmount.integrators.paths import EMPTY
from lensmount.integrators.photon_mapping.photon_gather import BIAS_LADDER
from lensmount.integrators.photon_mapping.photon_target import UNIFORM_SHARE
from lensmount.integrators.plan import edge_flux_components

_STATE_VERSION = 10  # 2: elapsed time; 3: energy ledger; 4: diagnostics; 5: each pass's half-radius flux and radius
# scale; 6: path signatures and per-face light (`analysis.paths.PathSums`); 7: each pass's path of largest excess;
# 8: each pass's flux on the ladder of radii instead of at half the radius; 9: each pass's largest terms;
# 10: each pass's bound on a term
ZERO_SIGNAL_COUNT = 3.0  # 95 % Poisson bound on the expected count when none was seen (−ln 0.05)
TAIL_P = 0.01  # the largest pass is an outlier below this p-value: 1 % of runs with normal passes are flagged
# ... and dominates only at this many medians: on case 1 the last pass (smallest radius, the noisiest) at 1.10×
# among seven within ±2.6 % is an outlier by the test (seed 25, p = 0.004) but moves the mean by 1.3 %
TAIL_RATIO = 1.5
# The tail of the terms a pass sums (`tail_index`). Hill's estimate from the run's TAIL_K largest (±1/√64 = 12 %
# of α); with fewer than TAIL_MIN + 1 positive terms kept there is no estimate. From LIGHT_TAIL on the fourth
# moment is finite, the spread's own variance converges (MCNP's variance of the variance) and the spread is the
# error bar; at 3 (MCNP's slope test) Pareto terms still held the truth in only 92 % of the runs. At or below
# UNBOUNDED_TAIL the allowance x_max α/(α − 1) has no bound. Not at 2 (infinite variance): case 1's gathered
# terms read α = 1.3–1.6 in its first passes while its largest term is 10⁻⁴ of a pass, an allowance of 0.02 %.
# Measured on sums of 50 and 500 Pareto, lognormal and exponential terms a pass (benchmarks/stopping_coverage.py
# terms): ≥ 94 % of the runs hold the truth or say they have no error bar, where the spread alone held 61–93 %
# (docs/accuracy.md).
TAIL_K = 64
TAIL_MIN = 16
# Weight classes: terms in a few sizes (a forward photon after one bounce, after two: Φρ, Φρ²) are no power law,
# and Hill's estimate across them reads the ratio of the classes (Cooke triplet at 35°: α = 0.33 from
# 8.9e-5 and 4.5e-6). The largest terms are classes when, split wherever one is CLASS_GAP times the next, every
# group spans at most CLASS_WIDTH: continuous terms with α < 10 span more than that over the TAIL_K largest.
CLASS_GAP = 2.0
CLASS_WIDTH = 1.5
UNBOUNDED_TAIL = 1.0
LIGHT_TAIL = 4.0


@dataclass
class Tail:
    """The largest pass against the others.

    largest_pass : its index in the run; over_median : largest / median (None when the median is 0)
    share : its share of the sum of the passes
    p : one-sided p-value of Grubbs's test that the largest pass belongs with the others (normal
        passes); 1 when undefined (fewer than MIN_PASSES, no spread)
    heavy : p < TAIL_P and the largest pass is at least TAIL_RATIO medians (or the median is 0): one
        pass dominates; the spread is no error bar for this run
    path : signature of the path whose flux in that pass most exceeded its mean over the passes before
        (`analysis.paths`; EMPTY when the passes carry no paths)
    index : the tail index α of the terms the passes sum (`tail_index` over every pass's largest terms);
        None when the passes keep none (or fewer than TAIL_MIN + 1 positive), inf when the largest are equal
    allowance : what the error bar adds for that tail (mm²): 0 from LIGHT_TAIL on, inf at or below
        UNBOUNDED_TAIL (no error bar); between, x_max α / ((α − 1) n): with N terms in the run and a
        tail x^−α, about one term of the next N exceeds the largest seen, x_max, and carries x_max α/(α − 1)
        on average, 1/n of it in the run's mean: what a run that has not met its tail yet misses. With a
        bound B on a term no index is fitted, and the allowance is B / n (one term at the bound) while no term
        within CLASS_GAP of B has been met, else 0
    bound : the largest a term of any pass could be (`PassEstimate.term_bound`, mm²); inf when not stated
    """

    largest_pass: int
    over_median: float | None
    share: float
    p: float
    heavy: bool
    path: int = EMPTY
    index: float | None = None
    allowance: float = 0.0
    bound: float = math.inf


@dataclass
class Drift:
    """First-half vs second-half means of the total flux.

    relative : (second − first) / overall mean (0 when the mean is 0)
    z : the difference over its own standard error (0 when that is 0 or n < 4)
    p : two-sided p-value of Welch's t-test on the two halves (1 when undefined). With
        few passes z is far from normal (|z| > 2 happens 17 % of the time at n = 4),
        so judge significance by p, not by z.
    """

    relative: float
    z: float
    p: float = 1.0


@dataclass
class Accumulator:
    """Sums over passes. Build with `Accumulator.empty(shape, part_names, pixel_area_mm2)`.

    n : passes added
    sum_image, sumsq_image : (ny, nx) Σ Ê_i and Σ Ê_i² (normalised irradiance E/E_sun)
    sum_parts : (P, ny, nx) Σ of the per-part images
    pass_flux : list of each pass's total flux (mm², normalised), in pass order
    pass_part_flux : list of each pass's (P,) per-part flux
    pass_part_flux_ladder : list of each pass's (L, P) per-part flux with its gather radii on the
        ladder (`photon_gather.BIAS_LADDER`; every rung equal to `pass_part_flux` for passes without a
        density estimate)
    pass_radius_scale : list of each pass's radius scale s_i (0 without a density estimate)
    photons, lost_flux : totals over the passes
    ledger : Σ over the passes of each energy-ledger entry (mm², `PassEstimate.ledger`)
    diagnostics : Σ over the passes of each count in `PassEstimate.diagnostics`
    last_pass : index of the last pass added (-1 before any)
    elapsed_s : wall time spent on the passes, summed over resumed parts of a run
    paths : per path signature and per CAD face sums (`analysis.paths.PathSums`) of the passes that carry them
    pass_excess_path : per pass, the signature of the path whose flux most exceeded its mean over the
        passes before it (EMPTY without paths): where a dominant pass's light came from (`tail`)
    pass_largest : per pass, its LARGEST largest terms (mm², `PassEstimate.largest`; zeros when it kept none)
    pass_term_bound : per pass, the largest a term of it could be (mm², `PassEstimate.term_bound`; inf: not stated)
    """

    part_names: list[str]
    pixel_area_mm2: float
    sum_image: np.ndarray
    sumsq_image: np.ndarray
    sum_parts: np.ndarray
    n: int = 0
    photons: int = 0
    lost_flux: float = 0.0
    last_pass: int = -1
    elapsed_s: float = 0.0
    pass_flux: list[float] = field(default_factory=list)
    pass_part_flux: list[np.ndarray] = field(default_factory=list)
    ledger: dict[str, float] = field(default_factory=dict)
    diagnostics: dict[str, float] = field(default_factory=dict)
    pass_part_flux_ladder: list[np.ndarray] = field(default_factory=list)
    pass_radius_scale: list[float] = field(default_factory=list)
    paths: PathSums = field(default_factory=PathSums)
    pass_excess_path: list[int] = field(default_factory=list)
    pass_largest: list[np.ndarray] = field(default_factory=list)
    pass_term_bound: list[float] = field(default_factory=list)

    @classmethod
    def empty(cls, shape: tuple[int, int], part_names: list[str], pixel_area_mm2: float) -> "Accumulator":
        ny, nx = shape
        return cls(list(part_names), float(pixel_area_mm2), np.zeros((ny, nx)), np.zeros((ny, nx)),
                   np.zeros((len(part_names), ny, nx)))

    # -- adding passes -------------------------------------------------------------------

    def add(self, estimate: PassEstimate, pass_index: int | None = None) -> None:
        """Add one pass. Non-finite pixels are a bug upstream; they are refused, not hidden."""
        image = np.asarray(estimate.image, dtype=np.float64)
        parts = np.asarray(estimate.per_part, dtype=np.float64)
        if image.shape != self.sum_image.shape:
            raise ValueError(f"pass image {image.shape} != accumulator {self.sum_image.shape}")
        if list(estimate.part_names) != self.part_names:
            raise ValueError("pass part names differ from the accumulator's")
        if not (np.isfinite(image).all() and np.isfinite(parts).all()):
            raise ValueError("pass estimate contains NaN or Inf")
        self.sum_image += image
        self.sumsq_image += image * image
        self.sum_parts += parts
        self.n += 1
        self.photons += int(estimate.photons)
        self.lost_flux += float(estimate.lost_flux)
        for key, value in estimate.ledger.items():
            if not np.isfinite(value):
                raise ValueError(f"pass energy ledger entry '{key}' is not finite")
            self.ledger[key] = self.ledger.get(key, 0.0) + float(value)
        for key, value in estimate.diagnostics.items():
            self.diagnostics[key] = self.diagnostics.get(key, 0.0) + float(value)
        self.pass_flux.append(float(image.sum() * self.pixel_area_mm2))
        part_flux = parts.sum(axis=(1, 2)) * self.pixel_area_mm2
        rungs = (np.tile(part_flux, (len(BIAS_LADDER), 1)) if estimate.part_flux_ladder is None
                 else np.asarray(estimate.part_flux_ladder, np.float64))
        if rungs.shape != (len(BIAS_LADDER), len(part_flux)) or not np.isfinite(rungs).all():
            raise ValueError("pass flux on the ladder of radii has the wrong shape or is not finite")
        self.pass_part_flux.append(part_flux)
        self.pass_part_flux_ladder.append(rungs)
        self.pass_radius_scale.append(float(estimate.radius_scale))
        self.pass_excess_path.append(EMPTY if estimate.paths is None else _excess_path(self.paths, estimate.paths))
        largest = np.zeros(LARGEST) if estimate.largest is None else np.asarray(estimate.largest, np.float64)
        if largest.shape != (LARGEST,) or not np.isfinite(largest).all():
            raise ValueError("pass's largest terms have the wrong shape or are not finite")
        self.pass_largest.append(largest)
        bound = float(estimate.term_bound)
        if not bound >= 0:
            raise ValueError("pass's bound on a term is negative or NaN")
        self.pass_term_bound.append(bound)
        if estimate.paths is not None:
            self.paths.add(estimate.paths, estimate.faces)
        self.last_pass = self.last_pass + 1 if pass_index is None else int(pass_index)

    # -- the answer ------------------------------------------------------------------------

    @property
    def mean_image(self) -> np.ndarray:
        """(ny, nx) mean normalised irradiance E/E_sun (zeros before any pass)."""
        return self.sum_image / max(self.n, 1)

    @property
    def mean_parts(self) -> np.ndarray:
        """(P, ny, nx) mean per-part normalised irradiance."""
        return self.sum_parts / max(self.n, 1)

    @property
    def std_error_image(self) -> np.ndarray:
        """(ny, nx) standard error per pixel from the spread of the passes, × `t_factor` (zeros for n < 2)."""
        if self.n < 2:
            return np.zeros_like(self.sum_image)
        mean = self.sum_image / self.n
        var = np.maximum(self.sumsq_image / self.n - mean * mean, 0.0) * self.n / (self.n - 1)
        return np.sqrt(var / self.n) * t_factor(self.n)

    @property
    def flux(self) -> float:
        """Mean detector stray flux normalised by E_sun (mm²)."""
        return float(np.mean(self.pass_flux)) if self.n else 0.0

    @property
    def flux_std_error(self) -> float:
        """Standard error of `flux`: batch means over passes, × `t_factor`, plus the tail allowance of heavy-tailed
        terms (`Tail.allowance`: the spread of passes that have not met their tail yet is too small); inf below
        MIN_PASSES and where the terms' tail has no bound (unknown)."""
        return _std_error(np.asarray(self.pass_flux)) + self.tail().allowance

    @property
    def part_flux(self) -> np.ndarray:
        """(P,) mean flux per part (mm²)."""
        if not self.n:
            return np.zeros(len(self.part_names))
        return np.mean(np.asarray(self.pass_part_flux), axis=0)

    @property
    def part_flux_std_error(self) -> np.ndarray:
        """(P,) standard error of the per-part flux (× `t_factor`); inf below MIN_PASSES."""
        if self.n < MIN_PASSES:
            return np.full(len(self.part_names), math.inf)
        series = np.asarray(self.pass_part_flux)
        return np.array([_std_error(series[:, p]) for p in range(series.shape[1])])

    def bias_bound(self) -> tuple[BiasBound, list[BiasBound]]:
        """(total, per part) kernel bias of `flux` and `part_flux` (`analysis.bias.BiasBound`, mm²): a
        bound from each pass's flux on the ladder of radii (same photons, same hit points), or none
        with the reason when the ladder's shape is not a bias c·r^k with 1 ≤ k ≤ 2. bound inf below
        MIN_PASSES; 0 for passes without a density estimate (forward)."""
        if self.n < MIN_PASSES:
            return BiasBound(math.inf), [BiasBound(math.inf) for _ in self.part_names]
        ladder = np.asarray(self.pass_part_flux_ladder)  # (n, L, P)
        parts = np.asarray(self.pass_part_flux)
        per_part = [ladder_bias(parts[:, p], ladder[:, :, p], t_factor) for p in range(len(self.part_names))]
        return ladder_bias(np.asarray(self.pass_flux), ladder.sum(axis=2), t_factor), per_part

    def upper_bound(self) -> float | None:
        """95 % upper bound on `flux` (mm²) when every pass was exactly zero, else None
        (`no_signal_bound`)."""
        if self.n == 0 or self.photons == 0 or any(f != 0.0 for f in self.pass_flux):
            return None
        return self.no_signal_bound()

    def no_signal_bound(self) -> float:
        """95 % upper bound (mm²) on the mean flux of anything that read exactly zero in every pass
        (the total, or one part): none of the N photons of the n passes reached it, so the expected
        count over the run is below 3 (Poisson, e^−3 ≈ 0.05); a photon carries at most the largest
        emitted weight w_max of its pass, and the run's flux is the mean over its passes, so
        flux < 3 · w_max / n. w_max is the mean weight Σ source / N, or 1 / UNIFORM_SHARE of it
        in passes that aim photons at the diaphragm edge (the disc's uniform share carries the
        heaviest ones: A_S / (N_pass · UNIFORM_SHARE)). inf before any photon."""
        if self.n == 0 or self.photons == 0:
            return math.inf
        mean_weight = self.ledger.get("source", 0.0) / self.photons  # A_S / N_pass, averaged over passes
        heaviest = 1.0 / UNIFORM_SHARE if self.diagnostics.get(AIMED_PASSES, 0.0) > 0 else 1.0
        return ZERO_SIGNAL_COUNT * mean_weight * heaviest / self.n

    def rel_error(self) -> float:
        """Relative uncertainty of the total flux for the stopping rule: (standard error, with its tail
        allowance, + bias bound) / |flux|. inf when unknown: n < MIN_PASSES, no signal (a zero mean: more
        passes are what could show light, never a reason to stop), a bias the ladder cannot bound, and
        terms whose tail has no bound (`Tail.allowance`)."""
        if self.n < MIN_PASSES:
            return math.inf
        mean = abs(self.flux)
        bias = self.bias_bound()[0]
        if mean == 0 or bias.bound is None:
            return math.inf
        return (self.flux_std_error + bias.bound) / mean

    def tail(self) -> Tail:
        """The largest pass against the others and the tail of the terms (`Tail`). Terms with a stated bound
        (`pass_term_bound`): the largest pass by `bounded_outlier_p`, no index, the allowance one term at the
        bound; otherwise Grubbs's test on the passes' totals and the index of the terms (`tail_index`)."""
        f = np.asarray(self.pass_flux, np.float64)
        if not len(f):
            return Tail(-1, None, 0.0, 1.0, False)
        k = int(np.argmax(f))
        median, total = float(np.median(f)), float(f.sum())
        bound = max(self.pass_term_bound)
        terms = np.concatenate(self.pass_largest)
        if math.isfinite(bound):
            # one term at the bound the run may not have met, unless it met that class (within CLASS_GAP)
            unmet = float(terms.max()) * CLASS_GAP < bound
            p, index, allowance = bounded_outlier_p(f, bound), math.nan, bound / self.n if unmet else 0.0
        else:
            p, index = grubbs_p(f), float(tail_index(terms))
            allowance = float(tail_allowance(index, float(terms.max()), self.n))
        ratio = f[k] / median if median > 0 else None
        return Tail(self.last_pass - self.n + 1 + k, ratio, f[k] / total if total > 0 else 0.0, p,
                    p < TAIL_P and (ratio is None or ratio >= TAIL_RATIO),
                    int(self.pass_excess_path[k]) if k < len(self.pass_excess_path) else EMPTY,
                    None if math.isnan(index) else index, allowance, bound)

    def converged(self, target_rel_error: float) -> bool:
        """The relative error is at most the target and no single pass dominates (`tail`): a run that
        has met a rare event once cannot quote its error from the spread, and one that stops on a
        low spread before meeting it reads low (optional stopping). The relative error holds the
        tail allowance of heavy-tailed terms and is unknown (never met) where that has no bound. Nor while the aimed
        photons' uniform or wide components carry the edge's light in few heavy photons
        (`plan.edge_flux_components`: the learned ring misses part of the lit edge)."""
        return (self.rel_error() <= target_rel_error and not self.tail().heavy
                and "warning" not in edge_flux_components(self.diagnostics, int(self.diagnostics.get(AIMED_PASSES, 0))))

    def drift(self) -> Drift:
        """First-half vs second-half means of the total flux (the radius bias indicator)."""
        f = np.asarray(self.pass_flux)
        if len(f) < 4:
            return Drift(0.0, 0.0, 1.0)
        h = len(f) // 2
        a, b = f[:h], f[h:]
        diff = float(b.mean() - a.mean())
        mean = float(f.mean())
        rel = diff / mean if mean != 0 else 0.0
        se = math.hypot(_std_error(a), _std_error(b))
        z = diff / se if se > 0 and math.isfinite(se) else 0.0
        p = 1.0
        if se > 0 and math.isfinite(se):
            from scipy.stats import ttest_ind  # lazy: keeps lensmount --help from loading scipy.stats

            p = float(ttest_ind(b, a, equal_var=False).pvalue)
            p = p if math.isfinite(p) else 1.0
        return Drift(rel, z, p)

    @property
    def mean_ledger(self) -> dict[str, float]:
        """The energy ledger per pass (mean over the passes), mm²."""
        return {k: v / max(self.n, 1) for k, v in sorted(self.ledger.items())}

    # -- checkpoint ------------------------------------------------------------------------

    def save(self, path: str | os.PathLike, **meta) -> None:
        """Write the state to an .npz atomically; `meta` (seed, input_hash, method, ...) goes along."""
        path = Path(path)
        arrays = dict(
            version=np.int64(_STATE_VERSION), n=np.int64(self.n), photons=np.int64(self.photons),
            lost_flux=np.float64(self.lost_flux), last_pass=np.int64(self.last_pass),
            elapsed_s=np.float64(self.elapsed_s),
            pixel_area_mm2=np.float64(self.pixel_area_mm2), part_names=np.array(self.part_names, dtype=str),
            sum_image=self.sum_image, sumsq_image=self.sumsq_image, sum_parts=self.sum_parts,
            pass_flux=np.asarray(self.pass_flux, dtype=np.float64),
            pass_part_flux=np.asarray(self.pass_part_flux, dtype=np.float64).reshape(-1, len(self.part_names)),
            ledger_keys=np.array(sorted(self.ledger), dtype=str),
            ledger_values=np.array([self.ledger[k] for k in sorted(self.ledger)], dtype=np.float64),
            diagnostics_keys=np.array(sorted(self.diagnostics), dtype=str),
            diagnostics_values=np.array([self.diagnostics[k] for k in sorted(self.diagnostics)], dtype=np.float64),
            pass_part_flux_ladder=np.asarray(self.pass_part_flux_ladder, dtype=np.float64).reshape(
                -1, len(BIAS_LADDER), len(self.part_names)),
            pass_radius_scale=np.asarray(self.pass_radius_scale, dtype=np.float64),
            pass_excess_path=np.asarray(self.pass_excess_path, dtype=np.int64),
            pass_largest=np.asarray(self.pass_largest, dtype=np.float64).reshape(-1, LARGEST),
            pass_term_bound=np.asarray(self.pass_term_bound, dtype=np.float64),
            **self.paths.arrays(),
        )
        for key, value in meta.items():
            arrays[f"meta_{key}"] = np.array(value)
        write_npz(path, compressed=True, **arrays)  # stray-light images are mostly zeros: ~20x smaller

    @classmethod
    def load(cls, path: str | os.PathLike) -> tuple["Accumulator", dict]:
        """The state and its meta dict (values as Python scalars/strings). InputError naming the
        file when it is damaged (truncated, empty, a flipped bit: the zip's CRCs see those) or
        not a checkpoint this version writes."""
        try:
            acc, meta = cls._read(path)
        except InputError:
            raise
        except NPZ_DAMAGE as e:
            raise InputError(f"the checkpoint is damaged and cannot be resumed ({type(e).__name__}: {e})",
                             file=str(path), valid="a checkpoint as lensmount wrote it: restore a copy, or delete "
                                                   "it and run again without --resume (its passes are lost)") from None
        series = (acc.pass_flux, acc.pass_part_flux, acc.pass_part_flux_ladder, acc.pass_radius_scale, acc.pass_largest,
                  acc.pass_term_bound)
        shapes = {acc.sum_image.shape, acc.sumsq_image.shape, acc.sum_parts.shape[1:]}
        if any(len(x) != acc.n for x in series) or len(shapes) != 1 or acc.n < 0 or not all(
                np.isfinite(a).all() for a in (acc.sum_image, acc.sumsq_image, acc.sum_parts)):
            raise InputError(f"the checkpoint is damaged: its {acc.n} passes and their sums do not agree",
                             file=str(path), valid="a checkpoint as lensmount wrote it: restore a copy, or delete "
                                                   "it and run again without --resume (its passes are lost)")
        return acc, meta

    @classmethod
    def _read(cls, path) -> tuple["Accumulator", dict]:
        with np.load(path, allow_pickle=False) as z:
            if int(z["version"]) != _STATE_VERSION:
                raise InputError(f"the checkpoint has layout version {int(z['version'])}, this lensmount reads "
                                 f"{_STATE_VERSION}", file=str(path),
                                 valid="a checkpoint this lensmount version wrote; run again without --resume")
            names = [str(s) for s in z["part_names"]]
            acc = cls(names, float(z["pixel_area_mm2"]), z["sum_image"].copy(), z["sumsq_image"].copy(),
                      z["sum_parts"].copy(), n=int(z["n"]), photons=int(z["photons"]),
                      lost_flux=float(z["lost_flux"]), last_pass=int(z["last_pass"]),
                      elapsed_s=float(z["elapsed_s"]),
                      pass_flux=[float(v) for v in z["pass_flux"]],
                      pass_part_flux=[row.copy() for row in z["pass_part_flux"]],
                      ledger={str(k): float(v) for k, v in zip(z["ledger_keys"], z["ledger_values"])},
                      diagnostics={str(k): float(v) for k, v in zip(z["diagnostics_keys"], z["diagnostics_values"])},
                      pass_part_flux_ladder=[rungs.copy() for rungs in z["pass_part_flux_ladder"]],
                      pass_radius_scale=[float(v) for v in z["pass_radius_scale"]],
                      paths=PathSums.from_arrays(z),
                      pass_excess_path=[int(v) for v in z["pass_excess_path"]],
                      pass_largest=[row.copy() for row in z["pass_largest"]],
                      pass_term_bound=[float(v) for v in z["pass_term_bound"]])
            meta = {k[5:]: z[k].item() for k in z.files if k.startswith("meta_")}
        return acc, meta


def tail_index(terms: np.ndarray) -> np.ndarray:
    """Hill's estimate of the tail index α (P(term > x) ∝ x^−α) from the TAIL_K + 1 largest positive terms of
    each row of `terms` (..., m), any order: α̂ = k / Σ_{i<k} ln(x_(i) / x_(k)), k = min(TAIL_K, positive − 1).
    nan with fewer than TAIL_MIN + 1 positive terms; inf when the k + 1 largest come in weight classes (`CLASS_GAP`,
    `CLASS_WIDTH`; all equal: equal photons), which have no power-law tail to fit.
    Vectorised over rows (benchmarks/stopping_coverage.py runs a thousand runs at once)."""
    x = -np.sort(-np.asarray(terms, np.float64), axis=-1)[..., :TAIL_K + 1]
    positive = (x > 0).sum(axis=-1)
    k = np.minimum(positive - 1, TAIL_K)
    ref = np.take_along_axis(x, np.maximum(k, 0)[..., None], axis=-1)
    used = np.arange(x.shape[-1]) < k[..., None]
    logs = np.where(used, np.log(np.where(used, x, 1.0) / np.where(ref > 0, ref, 1.0)), 0.0).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = np.where(logs > 0, k / np.where(logs > 0, logs, 1.0), np.inf)
    return np.where(k >= TAIL_MIN, np.where(_weight_classes(x, k), np.inf, alpha), np.nan)


def _weight_classes(x: np.ndarray, k: np.ndarray) -> np.ndarray:
    """(...,) True where the k + 1 largest terms of each row of x (..., m), descending, come in classes: split
    wherever one exceeds the next CLASS_GAP times, no group spans more than CLASS_WIDTH."""
    pair = np.arange(x.shape[-1] - 1) < k[..., None]  # ratio of term i to term i + 1, both among the k + 1
    with np.errstate(divide="ignore", invalid="ignore"):
        step = np.where(pair, np.log(np.where(pair, x[..., :-1], 1.0) / np.where(pair, x[..., 1:], 1.0)), 0.0)
    split = pair & (step > math.log(CLASS_GAP))
    span = np.cumsum(np.where(split, 0.0, step), axis=-1)
    span = span - np.maximum.accumulate(np.where(split, span, 0.0), axis=-1)  # since the group began
    return span.max(axis=-1, initial=0.0) <= math.log(CLASS_WIDTH)


def bounded_outlier_p(series: np.ndarray, bound: float) -> float:
    """p-value that the largest of n passes belongs with the others when each pass sums independent terms in
    [0, bound]. Such a pass F has variance at most bound · E[F], so by Bennett's inequality
    P(F − μ ≥ t) ≤ exp(−(μ/B) h(t/μ)), h(u) = (1 + u) ln(1 + u) − u (a Poisson count of μ/B terms at the bound:
    the skew of a few heavy terms a pass, which a normal test takes for an outlier); the largest of n passes
    gets Šidák's 1 − (1 − p₁)ⁿ. μ is the mean of all n passes (with the largest: a pass holding the run's
    only heavy term is no outlier). 1 below MIN_PASSES or without signal."""
    n = len(series)
    mean, top = float(np.mean(series)) if n else 0.0, float(np.max(series)) if n else 0.0
    if n < MIN_PASSES or not bound > 0 or not mean > 0 or not top > mean:
        return 1.0
    u = (top - mean) / mean
    p1 = math.exp(-(mean / bound) * ((1.0 + u) * math.log1p(u) - u))
    return 1.0 if p1 >= 1.0 else float(-math.expm1(n * math.log1p(-p1)))


def tail_allowance(index, largest, n):
    """What the error bar adds for terms of tail index `index` (`Tail.allowance`, mm²): 0 when unknown (nan) or
    at least LIGHT_TAIL, inf at or below UNBOUNDED_TAIL, else largest · α / ((α − 1) n). Vectorised."""
    index = np.asarray(index, np.float64)
    widen = (index > UNBOUNDED_TAIL) & (index < LIGHT_TAIL)
    a = np.where(widen, index, 2.0 * LIGHT_TAIL)
    return np.where(index <= UNBOUNDED_TAIL, np.inf,
                    np.where(widen, largest * a / ((a - 1.0) * np.maximum(n, 1)), 0.0))


def grubbs_p(series: np.ndarray) -> float:
    """One-sided p-value that the largest value belongs with the others, were they normal: Grubbs's
    G = (max − mean)/s, p ≤ n · P(T_{n−2} > t), t² = n(n−2)G² / ((n−1)² − nG²) (the Bonferroni
    form, exact where p is small). 1 below MIN_PASSES or without spread; 0 when the largest pass
    holds all the spread (every other pass equal)."""
    n = len(series)
    if n < MIN_PASSES:
        return 1.0
    s = float(np.std(series, ddof=1))
    if not s > 0:
        return 1.0
    g2 = ((float(np.max(series)) - float(np.mean(series))) / s) ** 2
    room = (n - 1) ** 2 - n * g2
    if room <= 1e-12 * (n - 1) ** 2:
        return 0.0
    from scipy.stats import t  # lazy: keeps lensmount --help from loading scipy.stats

    return float(min(1.0, n * t.sf(math.sqrt(n * (n - 2) * g2 / room), n - 2)))


def _excess_path(sums: PathSums, paths) -> int:
    """The signature of the path whose flux in this pass (`PassPaths`) most exceeds its mean over the
    passes summed so far; EMPTY when the pass has no stray path."""
    stray = paths.signature != EMPTY
    if not stray.any():
        return EMPTY
    sig, flux = paths.signature[stray], paths.flux[stray]
    before = np.zeros(len(sig))
    if sums.n and len(sums.signature):
        at = np.minimum(np.searchsorted(sums.signature, sig), len(sums.signature) - 1)
        seen = sums.signature[at] == sig
        before[seen] = sums.total[at[seen]] / sums.n
    return int(sig[int(np.argmax(flux - before))])


def _std_error(series: np.ndarray) -> float:
    """Sample standard deviation / √n of a 1-D series × `t_factor`; inf below MIN_PASSES values."""
    n = len(series)
    if n < MIN_PASSES:
        return math.inf
    return float(np.std(series, ddof=1) / math.sqrt(n) * t_factor(n))


__all__ = ["Accumulator", "Drift", "Tail", "TAIL_P", "CLASS_GAP", "CLASS_WIDTH", "bounded_outlier_p",
           "TAIL_RATIO", "TAIL_K", "TAIL_MIN", "UNBOUNDED_TAIL",
           "LIGHT_TAIL", "grubbs_p", "tail_index", "tail_allowance"]
