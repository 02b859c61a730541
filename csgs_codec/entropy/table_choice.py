"""Encoder helper: which frozen Gaussian table codes a set of residuals in the fewest bits."""

from __future__ import annotations

import numpy as np

from csgs_codec.entropy.tables import TOTAL, gaussian_family


def table_costs(residuals: np.ndarray) -> np.ndarray:
    """Exact coded size in bits of ``residuals`` (N,) int under each table: (S,) float64.

    Counts the range-coded symbols at -log2(f / 2^16) each, and for escaped residuals the
    escape symbol plus their varint bytes (spec/FORMAT.md §16.3.3).
    """
    family = gaussian_family()
    r = np.asarray(residuals, dtype=np.int64)
    costs = np.zeros(family.count)
    if r.size == 0:
        return costs
    values, counts = np.unique(r, return_counts=True)
    for t, (half, freqs) in enumerate(zip(family.half_widths, family.freqs)):
        half = int(half)
        bits = -np.log2(freqs / TOTAL)
        inside = np.abs(values) <= half
        cost = float(np.sum(counts[inside] * bits[values[inside] + half]))
        if not inside.all():
            excess = (np.abs(values[~inside]) - half - 1) * 2 + 1
            varint_bytes = np.maximum(1, np.ceil(np.log2(excess + 1) / 7))
            cost += float(np.sum(counts[~inside] * (bits[2 * half + 1] + 8 * varint_bytes)))
        costs[t] = cost
    return costs


def best_table(residuals: np.ndarray) -> int:
    """Index of the table with the smallest :func:`table_costs` (the lowest index on ties)."""
    return int(np.argmin(table_costs(residuals)))
