"""`jit_cache.load_cached`: what a process that forks workers loads from numba's cache before the fork."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
KERNELS = ("from numba import njit, prange\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n\n"
           "@njit(cache=True, parallel=True)\ndef on_cores(a):\n    s = 0.0\n    for i in prange(a.shape[0]):\n"
           "        s += a[i]\n    return s\n")
SCRIPT = ("import sys; sys.path.insert(0, sys.argv[1]); import numpy as np, kernel_mod\n"
          "import numba.np.ufunc.parallel as par\n"
          "from lensmount.trace.jit_cache import load_cached\n"
          "n = load_cached(vars(kernel_mod))\n"
          "print(n, len(kernel_mod.twice.overloads), len(kernel_mod.on_cores.overloads), par._is_initialized,\n"
          "      sum(kernel_mod.twice.stats.cache_misses.values()))\n"
          "print(kernel_mod.twice(21), kernel_mod.on_cores(np.ones(4)))\n")


def test_cached_kernels_load_without_compiling_and_the_threading_layer_stays_off(tmp_path):
    """The signatures the cache holds are loaded, nothing is compiled, a kernel on every core is left for
    its first call (loading it starts the threading layer, not fork-safe), and a kernel whose source
    changed since its cache was written loads nothing (numba compiles it at its first call)."""
    module = tmp_path / "kernel_mod.py"
    module.write_text(KERNELS)
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}
    run = [sys.executable, "-c", SCRIPT, str(tmp_path)]

    def lines():
        done = subprocess.run(run, capture_output=True, text=True, env=env, timeout=600)
        assert done.returncode == 0, done.stderr
        return [line.split() for line in done.stdout.splitlines()]

    cold, result = lines()  # nothing cached yet: nothing loaded; the calls compile and write the cache
    assert cold == ["0", "0", "0", "False", "0"] and result == ["42", "4.0"]
    warm, result = lines()
    assert warm == ["1", "1", "0", "False", "0"] and result == ["42", "4.0"]
    module.write_text(KERNELS.replace("2 * x", "3 * x"))
    changed, result = lines()
    assert changed[:3] == ["0", "0", "0"] and result == ["63", "4.0"]
