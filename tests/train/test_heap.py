"""Handing freed heap memory back (csgs_codec/train/heap.py): callable anywhere, no effect on
values."""

from __future__ import annotations

import numpy as np

from csgs_codec.train.heap import release_freed_memory


def test_release_freed_memory_keeps_live_arrays_and_answers_a_bool():
    kept = np.arange(1 << 20, dtype=np.float64)
    freed = np.ones(1 << 24)
    del freed
    assert isinstance(release_freed_memory(), bool)
    assert kept[-1] == (1 << 20) - 1 and kept.sum() == (1 << 20) * ((1 << 20) - 1) / 2
