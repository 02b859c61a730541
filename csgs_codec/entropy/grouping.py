"""Grouping symbols by the model that codes them: the coding order shared by every coder."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np


def groups_by_key(keys: np.ndarray) -> Iterator[tuple[int, np.ndarray]]:
    """Yield (key, positions) for each key present, keys increasing, positions increasing.

    Args:
        keys: (N,) non-negative integers below 2^16 (table or context indices).

    This is the order in which encoder and decoder visit symbols (one constriction call per
    key), so it must stay exactly this: a stable sort of the keys.
    """
    if keys.size == 0:
        return
    order = np.argsort(keys.astype(np.uint16), kind="stable")  # linear-time radix sort
    ordered = keys[order]
    cuts = np.flatnonzero(ordered[1:] != ordered[:-1]) + 1
    starts = np.concatenate(([0], cuts)).tolist()
    ends = np.concatenate((cuts, [ordered.size])).tolist()
    for a, b in zip(starts, ends):
        yield int(ordered[a]), order[a:b]
