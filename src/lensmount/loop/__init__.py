"""The loop an engineer runs many times a day, as Python functions: regenerate → simulate → compare.

Each takes a typed options record and returns a typed result; the CLI modules only
parse options, call these and print. Scripts (and `report`, `converge`) call them
directly:

    from lensmount.loop import SimulateOptions, simulate
    result = simulate(SimulateOptions(Path("mylens"), Path("mylens/scenes/case1.toml"), passes=8))
    result.summary["stray_fraction"], result.paths["exr"]
"""

from lensmount.loop.compare import CompareOptions, CompareResult, compare
from lensmount.loop.history import HistoryOptions, history
from lensmount.loop.regenerate import RegenerateOptions, RegenerateResult, regenerate
from lensmount.loop.simulate import (Observer, PassStatus, SimulateOptions, SimulateResult, input_hash,
                                     simulate)
# The sweeps built on simulate live in lensmount.analysis; they are part of the loop's API too.
from lensmount.analysis.converge import ConvergeOptions, MethodCurve, converge  # noqa: E402
from lensmount.analysis.pst import PstOptions, PstResult, pst  # noqa: E402

__all__ = ["RegenerateOptions", "RegenerateResult", "regenerate", "SimulateOptions", "SimulateResult",
           "PassStatus", "Observer", "simulate", "input_hash", "CompareOptions", "CompareResult", "compare",
           "HistoryOptions", "history", "PstOptions", "PstResult", "pst", "ConvergeOptions", "MethodCurve", "converge"]
