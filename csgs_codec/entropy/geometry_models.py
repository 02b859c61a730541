"""Integer context models of the geometry coder and grouped coding through constriction.

Every probability the range coder sees is an integer frequency out of ``2^16`` derived from
integer symbol counts (spec/FORMAT.md §15.5), so encoder and decoder build
identical tables on any machine. A coding step (one level's flags or occupancies) is cut into
blocks of doubling size; within a block, symbols that share a context are coded with one
constriction call, contexts in increasing order, and the counts are updated after the block.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.entropy.coder_model import TOTAL, categorical_model
from csgs_codec.entropy.grouping import groups_by_key
from csgs_codec.errors import FormatError

#: Largest first block of a coding step (symbols coded before the tables are first updated).
FIRST_BLOCK = 1024


def normalized_frequencies(counts: np.ndarray) -> np.ndarray:
    """Turn symbol counts into frequency tables that sum to ``TOTAL``, every entry at least 1.

    Args:
        counts: (C, A) non-negative int64, one row per context, ``2 <= A <= 2^15``.

    Returns:
        (C, A) int64. A row of zeros gives the uniform table. Otherwise entry ``s`` is
        ``1 + floor(counts[s] * (TOTAL - A) / sum(counts))`` and what is left of ``TOTAL``
        goes to the first symbol with the largest count.
    """
    counts = np.asarray(counts, dtype=np.int64)
    rows, alphabet = counts.shape
    empty = counts.sum(axis=1) == 0
    effective = np.where(empty[:, None], 1, counts)
    sums = effective.sum(axis=1, keepdims=True)
    freqs = 1 + (effective * (TOTAL - alphabet)) // sums
    left = TOTAL - freqs.sum(axis=1)
    freqs[np.arange(rows), np.argmax(effective, axis=1)] += left
    return freqs


class AdaptiveCounts:
    """Symbol counts per context; tables are rebuilt only between blocks (never within one).

    Args:
        contexts: number of contexts C.
        alphabet: number of symbols A.
    """

    def __init__(self, contexts: int, alphabet: int) -> None:
        self.alphabet = alphabet
        self.counts = np.zeros((contexts, alphabet), np.int64)

    def frequencies(self) -> np.ndarray:
        """(C, A) int64 tables for the next block, each summing to ``TOTAL``."""
        return normalized_frequencies(self.counts)

    def age(self) -> None:
        """Keep the larger half of every count: ``c - floor(c / 2)`` (done once per level)."""
        self.counts -= self.counts >> 1

    def observe(self, contexts: np.ndarray, symbols: np.ndarray) -> None:
        """Add one to the count of each (context, symbol) pair."""
        flat = contexts.astype(np.int64) * self.alphabet + symbols.astype(np.int64)
        self.counts += np.bincount(flat, minlength=self.counts.size).reshape(self.counts.shape)


def block_bounds(m: int) -> list[int]:
    """Ends of the blocks a step of ``m`` symbols is cut into, increasing.

    The ends are ``m, m >> 1, m >> 2, ...`` down to the first value ``<= FIRST_BLOCK``, so
    blocks double in size and tables adapt quickly at the start of every level.
    """
    ends = [m]
    while ends[-1] > FIRST_BLOCK:
        ends.append(ends[-1] >> 1)
    return ends[::-1]




def encode_grouped(encoder, symbols: np.ndarray, contexts: np.ndarray,
                   stats: AdaptiveCounts) -> None:
    """Append ``symbols`` to a constriction ``RangeEncoder`` in blocks, one call per context.

    Args:
        encoder: ``constriction.stream.queue.RangeEncoder``.
        symbols: (M,) integers in ``[0, A)``.
        contexts: (M,) context ids in ``[0, C)``.
        stats: the adaptive counts; updated after every block.
    """
    start = 0
    for end in block_bounds(symbols.shape[0]):
        freqs = stats.frequencies()
        ctx, sym = contexts[start:end], symbols[start:end]
        for c, idx in groups_by_key(ctx):
            encoder.encode(sym[idx].astype(np.int32), categorical_model(freqs[c]))
        stats.observe(ctx, sym)
        start = end


def decode_grouped(decoder, contexts: np.ndarray, stats: AdaptiveCounts) -> np.ndarray:
    """Decode what :func:`encode_grouped` wrote: (M,) contexts -> (M,) int64 symbols."""
    out = np.zeros(contexts.shape[0], np.int64)
    start = 0
    for end in block_bounds(contexts.shape[0]):
        freqs = stats.frequencies()
        ctx = contexts[start:end]
        block = out[start:end]
        for c, idx in groups_by_key(ctx):
            try:
                block[idx] = decoder.decode(categorical_model(freqs[c]), idx.size)
            except (AssertionError, ValueError, RuntimeError, OverflowError) as exc:
                raise FormatError(f"geometry: range decoder failed ({exc})") from exc
        stats.observe(ctx, block)
        start = end
    return out
