"""Coverage of compare's 99 % interval on real passes (tools/verdict/real_passes.py output), issue 26."""
import math, numpy as np
from lensmount.analysis.compare import Measurement, interval
from lensmount.analysis.error_bar import t_factor
def run(x):
    n=len(x); return Measurement(float(x.mean()), float(x.std(ddof=1)/math.sqrt(n)*t_factor(n)), 0.0, n)
v = np.load("/tmp/verdict/passes-forward-2000.npy"); v = v[np.isfinite(v).all(axis=1)]
print("seeds", len(v), "passes", v.size, "rel sd", v.std()/v.mean())
# disjoint real runs: each seed's 8 passes = two 4-pass runs of different seeds' streams
runs = v.reshape(-1, 4)
rng = np.random.default_rng(0)
for n in (4,):
    idx = rng.permutation(len(runs)); pairs = [(runs[idx[2*k]], runs[idx[2*k+1]]) for k in range(len(runs)//2)]
    cov = np.mean([lo <= 0 <= hi for lo, hi in (interval(run(a), run(b), 0.99) for a, b in pairs)])
    print(f"disjoint real 4-pass pairs: {len(pairs)}, coverage {cov:.4f}")
pool = v.ravel()
for na, nb in ((3,3),(4,4),(4,8),(8,8)):
    c = np.mean([lo <= 0 <= hi for lo, hi in (interval(run(rng.choice(pool, na, replace=False)), run(rng.choice(pool, nb, replace=False)), 0.99) for _ in range(20000))])
    print(f"resampled real passes {na} vs {nb}: coverage {c:.4f} (20000 pairs)")
