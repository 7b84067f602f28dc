"""Across-seed summary of benchmarks/through_optics/through_optics_ref.py output files: per angle and method, the pooled mean, the
spread of the runs' means against what they quote (ratio), how many runs' 2σ cover the others' pooled mean,
and seconds a pass. python benchmarks/through_optics/through_optics_seeds.py FILE…"""

import collections
import re
import sys

import numpy as np

runs = collections.defaultdict(list)
for path in sys.argv[1:]:
    for line in open(path):
        m = re.match(r"\s*([\d.]+)° seed (\d+) (\w+)\s+mean (\S+) ± (\S+) .* ([\d.]+) s/pass", line)
        if m:
            runs[(float(m[1]), m[3])].append((float(m[4]), float(m[5]), float(m[6])))
for (angle, name), r in sorted(runs.items()):
    mean, err, sec = (np.array(c) for c in zip(*r))
    spread = mean.std(ddof=1)
    cover = sum(abs(mean[i] - np.delete(mean, i).mean()) <= 2 * err[i] for i in range(len(mean)))
    print(f"{angle:4.0f}° {name:4s} runs {len(mean)}  pooled {mean.mean():.3e} ± {spread / np.sqrt(len(mean)):.2e}  "
          f"spread of runs {100 * spread / mean.mean():.0f} %  median quoted {100 * np.median(err / mean):.0f} %  "
          f"ratio {spread / np.median(err):.2f}  2σ covers {cover}/{len(mean)}  {sec.mean():.1f} s/pass")
