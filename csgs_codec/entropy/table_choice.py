"""Encoder helper: which frozen Gaussian table codes a set of residuals in the fewest bits."""

from __future__ import annotations

from functools import cache

import numpy as np

from csgs_codec.entropy.tables import TOTAL, gaussian_family


@cache
def _symbol_bits() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The family's code lengths in one padded matrix: ((S, 2K+2) float64 bits of each
    table's symbols, K the largest half width, unused cells 0; (S,) int64 half widths;
    (S,) float64 bits of each table's escape symbol)."""
    family = gaussian_family()
    halves = np.asarray(family.half_widths, dtype=np.int64)
    bits = np.zeros((family.count, 2 * int(halves.max()) + 2))
    for t, freqs in enumerate(family.freqs):
        bits[t, :len(freqs)] = -np.log2(freqs / TOTAL)
    escapes = bits[np.arange(family.count), 2 * halves + 1].copy()
    bits.setflags(write=False)
    return bits, halves, escapes


def table_costs(residuals: np.ndarray) -> np.ndarray:
    """Exact coded size in bits of ``residuals`` (N,) int under each table: (S,) float64.

    Counts the range-coded symbols at -log2(f / 2^16) each, and for escaped residuals the
    escape symbol plus their varint bytes (spec/FORMAT.md §16.3.3). All tables at once over
    the distinct values (an (S, distinct values) matrix), as the encoder asks this for every
    channel and candidate step.
    """
    bits, halves, escapes = _symbol_bits()
    r = np.asarray(residuals, dtype=np.int64)
    if r.size == 0:
        return np.zeros(len(halves))
    values, counts = np.unique(r, return_counts=True)
    magnitude = np.abs(values)[None, :]
    half = halves[:, None]
    inside = magnitude <= half
    rows = np.arange(len(halves))[:, None]
    symbol = bits[rows, np.where(inside, values[None, :] + half, 0)]
    excess = np.maximum(magnitude - half - 1, 0) * 2 + 1
    varint_bytes = np.maximum(1, np.ceil(np.log2(excess + 1) / 7))
    escaped = escapes[:, None] + 8 * varint_bytes
    return np.where(inside, symbol, escaped) @ counts.astype(np.float64)


def best_table(residuals: np.ndarray) -> int:
    """Index of the table with the smallest :func:`table_costs` (the lowest index on ties)."""
    return int(np.argmin(table_costs(residuals)))
