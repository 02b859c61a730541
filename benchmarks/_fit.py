"""Small fits the benchmarks report: power-law growth exponents and Pareto fronts."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def growth_exponent(sizes: Sequence[float], values: Sequence[float]) -> float | None:
    """Least-squares slope of log(value) against log(size): the b of value ~ a * size^b.

    Pairs whose size or value is not a positive finite number are left out (a memory delta
    of 0 has no logarithm). None when fewer than two distinct sizes remain.
    """
    pairs = [(float(s), float(v)) for s, v in zip(sizes, values)
             if v is not None and _positive(s) and _positive(v)]
    if len({s for s, _ in pairs}) < 2:
        return None
    x = np.log([s for s, _ in pairs])
    y = np.log([v for _, v in pairs])
    slope, _ = np.polyfit(x, y, 1)
    return float(slope)


def pareto_optimal(costs: np.ndarray) -> np.ndarray:
    """Boolean (M,) mask of the rows of ``costs`` that no other row dominates.

    Args:
        costs: (M, K) float, every column a cost to minimise (negate what is to be
            maximised). NaN counts as the worst possible value.

    A row dominates another when it is no worse in every column and better in at least one.
    Rows with identical costs do not dominate each other, so both are kept.
    """
    c = np.asarray(costs, dtype=np.float64)
    if c.ndim != 2:
        raise ValueError(f"costs must be (M, K), got shape {c.shape}")
    c = np.where(np.isnan(c), np.inf, c)
    keep = np.ones(len(c), dtype=bool)
    for i in range(len(c)):
        no_worse = np.all(c <= c[i], axis=1)
        better = np.any(c < c[i], axis=1)
        keep[i] = not np.any(no_worse & better)
    return keep


def _positive(value: float) -> bool:
    return math.isfinite(value) and value > 0
