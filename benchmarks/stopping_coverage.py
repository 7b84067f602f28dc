"""Coverage of `--target-rel-error` runs on synthetic heavy-tailed passes (issue 29, item 4).

    python benchmarks/stopping_coverage.py RUNS MAX_PASSES TARGET...    e.g. 1000 400 0.2 0.05
    python benchmarks/stopping_coverage.py terms RUNS MAX_PASSES TERMS TARGET...    e.g. terms 400 200 50 0.05 0.02

`terms`: a pass is what the estimators make, a sum of TERMS independent heavy-tailed terms (Pareto, lognormal,
exponential); each pass keeps its `LARGEST` largest terms as `PassEstimate.largest` does, and the rule shipped
before (standard error + the dominant-pass test) is set against the one shipped now (`Accumulator.rel_error`:
no error bar while the terms' tail index `tail_index` is at most UNBOUNDED_TAIL, the tail allowance below
LIGHT_TAIL). A run is honest when its interval mean ± (2 se + allowance) holds the truth, or when it ends
(at MAX_PASSES) saying it has no error bar.

Each run adds passes drawn from one distribution and stops at the first n >= 8 (runner.Stopping's
min_passes) where the rule holds; a stopped run covers when |mean - truth| <= 2 x its quoted standard
error (batch means x Student's t, `analysis.error_bar.t_factor`). Rules: the shipped one (standard error
<= target x mean and no dominant pass: Grubbs p < TAIL_P and >= TAIL_RATIO medians), and candidates
tried on the way (Hill tail-index allowance, variance-of-variance, Cochran's n >= c G1^2). Also the
coverage of ±2 standard errors at a fixed number of passes, which bounds what any stopping rule
that quotes the plain standard error can reach. Vectorised over runs (cumulative sums per pass).
"""

import math
import sys

import numpy as np
from scipy.stats import t as student

from lensmount.analysis.error_bar import t_factor
from lensmount.analysis.passes import UNBOUNDED_TAIL, TAIL_K, TAIL_P, TAIL_RATIO, tail_allowance, tail_index
from lensmount.integrators.estimate import LARGEST


def distributions(rng, runs, passes):
    """name -> (runs x passes values, true mean)."""
    out = {}
    for s in (1.0, 1.5):
        out[f"lognormal sigma={s}"] = (rng.lognormal(0, s, (runs, passes)), math.exp(s * s / 2))
    for a in (2.0, 2.5, 3.0):
        out[f"Pareto alpha={a}"] = ((1 - rng.random((runs, passes))) ** (-1 / a), a / (a - 1))
    for p in (0.02, 0.05, 0.1):
        x = rng.normal(1.0, 0.05, (runs, passes)) * np.where(rng.random((runs, passes)) < p, 5.0, 1.0)
        out[f"5x events p={p}"] = (x, 1 + 4 * p)
    out["normal cv=0.3"] = (rng.normal(1.0, 0.3, (runs, passes)), 1.0)
    return out


def dominant(x, n, m, var, largest):
    """`Accumulator.tail().heavy`, vectorised over runs."""
    s = np.sqrt(var)
    g2 = np.where(s > 0, ((largest - m) / np.where(s > 0, s, 1)) ** 2, 0)
    room = (n - 1) ** 2 - n * g2
    tt = np.sqrt(np.maximum(n * (n - 2) * g2 / np.maximum(room, 1e-300), 0))
    p = np.where(room <= 1e-12 * (n - 1) ** 2, 0.0, np.minimum(1, n * student.sf(tt, n - 2)))
    p = np.where(s > 0, p, 1.0)
    return (p < TAIL_P) & (largest >= TAIL_RATIO * np.median(x, axis=1))


def hill(top, n, k):
    """Hill's tail index from the k largest values (top sorted descending)."""
    k = min(k, n - 1, top.shape[1] - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(top[:, k] > 0, k / np.log(top[:, :k] / top[:, k:k + 1]).sum(axis=1), 0.0)


RULES = {
    "shipped": lambda st: st["se"],
    "+ Hill allowance": lambda st: st["se"] + np.where(st["alpha"] > 1, st["top"][:, 0] / ((st["n"] + 1) * (st["alpha"] - 1)), np.inf),
    "VOV <= 0.1": lambda st: np.where(st["vov"] <= 0.1, st["se"], np.inf),
    "n >= 25 G1^2": lambda st: np.where(st["n"] >= 25 * st["g1"] ** 2, st["se"], np.inf),
}


def run(x, target, rule, min_passes=8, keep=16):
    runs, passes = x.shape
    stop, est, err = np.full(runs, -1), np.zeros(runs), np.zeros(runs)
    sums = [np.cumsum(x ** p, axis=1) for p in (1, 2, 3, 4)]
    top = np.full((runs, keep), -np.inf)
    for n in range(1, passes + 1):
        top = -np.sort(-np.concatenate([top, x[:, n - 1:n]], axis=1), axis=1)[:, :keep]
        if n < min_passes:
            continue
        s1, s2, s3, s4 = (c[:, n - 1] / n for c in sums)
        m = s1
        m2 = np.maximum(s2 - m * m, 0)
        m3 = s3 - 3 * m * s2 + 2 * m ** 3
        m4 = s4 - 4 * m * s3 + 6 * m * m * s2 - 3 * m ** 4
        var = m2 * n / (n - 1)
        se = np.sqrt(var / n) * t_factor(n)
        with np.errstate(divide="ignore", invalid="ignore"):
            st = dict(n=n, se=se, top=top, alpha=hill(top, n, max(3, int(math.sqrt(n)))),
                      vov=np.where(m2 > 0, m4 / (n * m2 * m2) - 1 / n, 0), g1=np.where(m2 > 0, m3 / m2 ** 1.5, 0))
        e = np.where(dominant(x[:, :n], n, m, var, top[:, 0]), np.inf, rule(st))
        now = ((e <= target * np.abs(m)) | (n == passes)) & (stop < 0)
        stop[now], est[now], err[now] = n, m[now], se[now]
    return stop, est, err


def term_distributions():
    """name -> (draw(rng, shape), mean of one term)."""
    out = {"exponential": (lambda rng, shape: rng.exponential(1.0, shape), 1.0)}
    for s in (1.0, 1.5, 2.0):
        out[f"lognormal sigma={s}"] = (lambda rng, shape, s=s: rng.lognormal(0, s, shape), math.exp(s * s / 2))
    for a in (1.5, 2.0, 2.5, 3.0, 4.0):
        out[f"Pareto alpha={a}"] = (lambda rng, shape, a=a: (1 - rng.random(shape)) ** (-1 / a), a / (a - 1))
    return out


def run_terms(draw, runs, passes, terms, target, seed=1, min_passes=8):
    """Both rules on the same passes: {rule: (stop, estimate, quoted half-width / 2, ended without an error bar)}."""
    rng = np.random.default_rng(seed)
    x = np.zeros((runs, passes))
    pool = np.zeros((runs, 0))  # the run's TAIL_K + 1 largest terms: all `tail_index` reads of every pass's LARGEST
    out = {r: (np.full(runs, -1), np.zeros(runs), np.zeros(runs), np.zeros(runs, bool)) for r in ("before", "now")}
    for n in range(1, passes + 1):
        t = draw(rng, (runs, terms))
        x[:, n - 1] = t.sum(axis=1)
        top = -np.partition(-t, LARGEST - 1, axis=1)[:, :LARGEST]
        pool = -np.sort(-np.concatenate([pool, top], axis=1), axis=1)[:, :TAIL_K + 1]
        if n < min_passes:
            continue
        m = x[:, :n].mean(axis=1)
        var = x[:, :n].var(axis=1, ddof=1)
        se = np.sqrt(var / n) * t_factor(n)
        heavy = dominant(x[:, :n], n, m, var, x[:, :n].max(axis=1))
        index = tail_index(pool)
        allowance = tail_allowance(index, pool[:, 0], n)
        for rule, err, no_bar in (("before", se, np.zeros(runs, bool)),
                                  ("now", se + allowance, index <= UNBOUNDED_TAIL)):
            stop, est, half, unbounded = out[rule]
            now = (((err <= target * np.abs(m)) & ~heavy & ~no_bar) | (n == passes)) & (stop < 0)
            stop[now], est[now], half[now], unbounded[now] = n, m[now], err[now], no_bar[now]
    return out


def main_terms(runs: int, passes: int, terms: int, targets: list[float]) -> None:
    for target in targets:
        print(f"{terms} terms a pass, target {100 * target:g} %, {runs} runs of at most {passes} passes: "
              "honest | stopped on the target | their median passes | their mean / truth")
        for name, (draw, mu) in term_distributions().items():
            row = []
            for rule, (stop, est, half, unbounded) in run_terms(draw, runs, passes, terms, target).items():
                done = stop < passes
                honest = unbounded | (np.abs(est - terms * mu) <= 2 * half)
                row.append(f"{rule}: {100 * honest.mean():5.1f} % | {100 * done.mean():3.0f} % | "
                           f"{np.median(stop[done]) if done.any() else float('nan'):4.0f} | "
                           f"{est[done].mean() / (terms * mu) if done.any() else float('nan'):.2f}")
            print(f"  {name:20s} " + "  ;  ".join(row), flush=True)


def main(runs: int, passes: int, targets: list[float]) -> None:
    data = distributions(np.random.default_rng(1), runs, passes)
    print("fixed n: coverage of mean ± 2 se (t)")
    for name, (x, mu) in data.items():
        row = []
        for n in (8, 32, 128, passes):
            m, se = x[:, :n].mean(1), x[:, :n].std(1, ddof=1) / math.sqrt(n) * t_factor(n)
            row.append(f"n={n}: {100 * np.mean(np.abs(m - mu) <= 2 * se):4.1f} %")
        print(f"  {name:20s} " + "  ".join(row))
    for target in targets:
        print(f"target {100 * target:g} %: coverage of stopped runs, share stopped, median n, mean / truth")
        for name, (x, mu) in data.items():
            row = []
            for rule_name, rule in RULES.items():
                stop, est, err = run(x, target, rule)
                done = stop < passes
                cover = np.abs(est - mu) <= 2 * err
                row.append(f"{rule_name}: {100 * cover[done].mean():4.1f} % ({100 * done.mean():3.0f} %, "
                           f"n~{np.median(stop[done]) if done.any() else float('nan'):.0f}, "
                           f"{est[done].mean() / mu if done.any() else float('nan'):.2f})")
            print(f"  {name:20s} " + " | ".join(row), flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "terms":
        main_terms(int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), [float(a) for a in sys.argv[5:]])
    else:
        main(int(sys.argv[1]), int(sys.argv[2]), [float(a) for a in sys.argv[3:]])
