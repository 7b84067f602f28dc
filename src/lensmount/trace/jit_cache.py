"""numba's on-disk cache (`cache=True`), checked before it is trusted.

numba keeps each kernel's compiled code beside its source: an index (`.nbi`) and one data
file (`.nbc`) per compiled signature, both pickles. A truncated, emptied or garbled file is
unpickled only inside the kernel's first call, where it raises `EOFError` or
`UnpicklingError` from deep in numba (a run died so with a traceback). So each kernel module
calls `drop_damaged(globals())` once at import: every cached kernel's index and data files
are unpickled here, and a kernel whose files do not load has its index emptied, so numba
compiles it again (and writes new files) on first use, as on a cold cache.

This reads numba's own cache objects (`Dispatcher._cache._cache_file`); numba ≥ 0.57.
"""

from __future__ import annotations

import pickle

from numba.core.dispatcher import Dispatcher


def drop_damaged(namespace: dict) -> list[str]:
    """Empty the cache index of every kernel in `namespace` whose cached files do not load;
    the names of those kernels."""
    dropped = []
    for name, kernel in namespace.items():
        if not isinstance(kernel, Dispatcher) or not kernel._cache.__class__.__name__ == "FunctionCache":
            continue
        files = kernel._cache._cache_file
        try:
            for data_name in files._load_index().values():
                files._load_data(data_name)
        except FileNotFoundError:
            pass  # an index naming a file that is gone: numba compiles that signature again itself
        except (OSError, EOFError, pickle.UnpicklingError, ValueError, TypeError, AttributeError, ImportError,
                IndexError, KeyError, MemoryError):
            kernel._cache.flush()
            dropped.append(name)
    return dropped


def load_cached(namespace: dict) -> int:
    """Load into this process every signature of the namespace's kernels that the cache holds for this
    machine and this source (`Dispatcher.compile` of a cached signature loads it; nothing is compiled,
    a signature the cache lacks waits for its first call); how many. A process that forks workers
    (`run.executor`) loads once for all of them, where each worker would load the same machine code in its
    first pass (~1 CPU s each, every run). Kernels on every core (`parallel=True`) are left out: loading one
    starts numba's threading layer (GNU OpenMP is not fork-safe), and a worker walks on one core."""
    loaded = 0
    for kernel in namespace.values():
        if not isinstance(kernel, Dispatcher) or not kernel._cache.__class__.__name__ == "FunctionCache" \
                or kernel.targetoptions.get("parallel"):
            continue
        codegen = kernel.targetctx.codegen()
        for key in kernel._cache._cache_file._load_index():
            if kernel._cache._index_key(key[0], codegen) == key:  # this machine's, of this source
                kernel.compile(key[0])
                loaded += 1
    return loaded


__all__ = ["drop_damaged", "load_cached"]
