"""SIGINT and SIGTERM at any moment: a stop the program handles, never a half-written state.

Batch schedulers send SIGTERM (and SIGKILL a little later); an engineer presses Ctrl-C; a
script that started a command in the background left SIGINT ignored. All three must end a
command the same way: what is complete is kept, nothing half-done is left behind, and the
command says how to continue and exits 143 (SIGTERM) or 130 (SIGINT).

`stop_on_signals()` makes both signals raise in the main thread (`KeyboardInterrupt`, or its
subclass `Terminated` for SIGTERM), also where SIGINT was inherited as ignored; the command
catches that where it knows what is complete. `deferred()` holds a signal back while a piece
of work that must not be cut in half runs (merging a pass into the sums, writing a set of
results), then raises it. Kept apart from the runner so the CLI imports it without numpy.
"""

from __future__ import annotations

import contextlib
import signal
import threading

EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}  # 128 + the signal: what shells and schedulers expect


class Terminated(KeyboardInterrupt):
    """SIGTERM (what batch schedulers send) stops a run the way Ctrl-C does: checkpoint, results, exit 143."""


def exit_code(stop: KeyboardInterrupt) -> int:
    """130 for SIGINT, 143 for SIGTERM."""
    return EXIT_CODES[signal.SIGTERM if isinstance(stop, Terminated) else signal.SIGINT]


def signal_name(stop: KeyboardInterrupt) -> str:
    return "SIGTERM" if isinstance(stop, Terminated) else "SIGINT"


_held: list[int] = []  # signals that arrived inside `deferred()`, in order
_depth = [0]  # nesting depth of `deferred()`


def _raise(signum: int) -> None:
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _handler(signum, frame) -> None:
    if _depth[0]:
        _held.append(signum)
        return
    _raise(signum)


@contextlib.contextmanager
def stop_on_signals():
    """Inside: SIGINT → KeyboardInterrupt, SIGTERM → Terminated, in the main thread (elsewhere no
    handler can be set, and the block runs unchanged). The previous handlers come back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in EXIT_CODES}
    for s in EXIT_CODES:
        signal.signal(s, _handler)
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


@contextlib.contextmanager
def deferred():
    """A signal arriving inside the block is raised when the block ends (not inside it)."""
    _depth[0] += 1
    try:
        yield
    except BaseException:  # the block failed or was stopped already: that ends the work, not a held signal
        _depth[0] -= 1
        if not _depth[0]:
            _held.clear()
        raise
    _depth[0] -= 1
    if not _depth[0] and _held:
        signum = _held[0]
        _held.clear()
        _raise(signum)


__all__ = ["Terminated", "stop_on_signals", "deferred", "exit_code", "signal_name", "EXIT_CODES"]
