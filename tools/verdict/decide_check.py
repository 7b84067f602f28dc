"""Predicted vs actual passes to decide: real pass values (or synthetic), a change = the new run's passes × factor."""
import math, sys
import numpy as np
from lensmount.analysis.compare import UNDECIDED, Measurement, judge, interval
from lensmount.analysis.error_bar import t_factor

def meas(x):
    n = len(x)
    return Measurement(float(np.mean(x)), float(np.std(x, ddof=1) / math.sqrt(n) * t_factor(n)), 0.0, n, n * 2000, float(n))

def trial(pool, rng, factor, n_old=8, n_new=4, tol=0.05, c=0.99, cap=4000):
    idx = rng.permutation(len(pool))
    old_src, new_src = pool[idx[: len(pool) // 2]], pool[idx[len(pool) // 2:]] * factor
    o, n = list(old_src[:n_old]), list(new_src[:n_new])
    v = judge(meas(o), meas(n), tol, c)
    if v.verdict != UNDECIDED or v.more_passes is None:
        return None
    a_o, a_n = v.more_passes
    share = a_o / max(a_o + a_n, 1)
    io, inn, added = n_old, n_new, 0
    while added < cap:
        # add passes in the predicted proportion
        if (io - n_old) <= share * (added + 1) and io < len(old_src):
            o.append(old_src[io]); io += 1
        elif inn < len(new_src):
            n.append(new_src[inn]); inn += 1
        else:
            return None
        added += 1
        lo, hi = interval(meas(o), meas(n), c)
        T = tol * abs(np.mean(o))  # judge's threshold, from the old run's value
        if lo > T or hi <= T:
            return a_o + a_n, added, "regression" if lo > T else "no regression"
    return None

if __name__ == "__main__":
    src = sys.argv[1]
    rng = np.random.default_rng(5)
    pool = np.load(src).ravel() if src != "gamma" else rng.gamma(3.4, 0.3, 4000)
    pool = pool[np.isfinite(pool)]
    print("pool", len(pool), pool.mean(), pool.std() / pool.mean())
    for factor in (1.0, 1.25, 1.5, 2.0):
        sys.stdout.flush()
        res = [r for r in (trial(pool, rng, factor) for _ in range(60)) if r]
        ratio = np.array([a / p for p, a, _ in res])
        print(f"factor {factor}: {len(res)} undecided trials decided; predicted median {np.median([p for p,_,_ in res]):.0f} "
              f"actual median {np.median([a for _,a,_ in res]):.0f}; actual/predicted median {np.median(ratio):.2f}, "
              f"within 3x {np.mean((ratio <= 3) & (ratio >= 1/3)):.2f}; verdicts {sorted(set(v for *_, v in res))}")
