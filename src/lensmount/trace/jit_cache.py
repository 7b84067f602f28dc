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


__all__ = ["drop_damaged"]
