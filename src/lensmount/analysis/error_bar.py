"""The error bar of a mean over passes: how many passes make one, and how Student's t widens it.

Shared by everything that quotes a standard error from the spread of passes (`analysis.passes`,
`analysis.paths`, `analysis.compare`)."""

from __future__ import annotations

import math

from scipy.special import stdtrit  # Student's t quantile; scipy.stats' t.ppf is ~70x slower per call

MIN_PASSES = 3  # below this the spread of the passes is no error bar (std error: inf)


def t_factor(n: int) -> float:
    """Student's t at 97.5 % with n − 1 degrees of freedom over the normal's 1.96.

    Multiplies the plain standard error from n passes so that ±2 of them cover ~95 % as
    they would with many passes (×1.31 at n = 6, ×1.12 at 12, ×1.02 at 64): six passes
    gave a spread 1.3× the quoted error over 16 seeds before."""
    if n < 2:
        return math.inf
    return float(stdtrit(n - 1, 0.975) / 1.959963984540054)


__all__ = ["MIN_PASSES", "t_factor"]
