"""Morton (Z-order) codes of integer 3D positions, the canonical point order of csgs geometry.

Bit ``i`` of x, y and z goes to bit ``3i``, ``3i + 1`` and ``3i + 2`` of the code, so sorting by
code visits an octree depth first with children in the order x fastest, then y, then z. Up to
21 bits per axis fit in the 63 low bits of a ``uint64``.
"""

from __future__ import annotations

import numpy as np

#: The most bits per axis a Morton code (and the geometry coder) supports.
MAX_BITS = 21

# Masks for spreading 21 bits to every third bit of a 64-bit word, widest step first.
_SPREAD_STEPS = (
    (32, 0x001F00000000FFFF),
    (16, 0x001F0000FF0000FF),
    (8, 0x100F00F00F00F00F),
    (4, 0x10C30C30C30C30C3),
    (2, 0x1249249249249249),
)
_LOW21 = np.uint64((1 << 21) - 1)
# The same masks undone narrowest step first (shift by 2 leaves the 4-step pattern, ...).
_COMPACT_STEPS = (
    (2, 0x10C30C30C30C30C3),
    (4, 0x100F00F00F00F00F),
    (8, 0x001F0000FF0000FF),
    (16, 0x001F00000000FFFF),
    (32, 0x00000000001FFFFF),
)


def _spread(values: np.ndarray) -> np.ndarray:
    """(N,) uint64 with at most 21 bits -> the same bits moved to positions 0, 3, 6, ..."""
    v = values & _LOW21
    for shift, mask in _SPREAD_STEPS:
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def _compact(codes: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_spread`: bits 0, 3, 6, ... of (N,) uint64 -> a 21-bit integer."""
    v = codes & np.uint64(_SPREAD_STEPS[-1][1])
    for shift, mask in _COMPACT_STEPS:
        v = (v | (v >> np.uint64(shift))) & np.uint64(mask)
    return v


def morton_encode(points: np.ndarray) -> np.ndarray:
    """Morton codes of integer positions.

    Args:
        points: (N, 3) non-negative integers below 2^21 (any integer dtype).

    Returns:
        (N,) uint64 codes; x occupies bits 0, 3, 6, ..., y bits 1, 4, ..., z bits 2, 5, ...
    """
    p = np.asarray(points).astype(np.uint64, copy=False)
    if p.shape[0] == 0:
        return np.zeros(0, np.uint64)
    x = _spread(p[:, 0])
    y = _spread(p[:, 1])
    z = _spread(p[:, 2])
    return x | (y << np.uint64(1)) | (z << np.uint64(2))


def morton_decode(codes: np.ndarray) -> np.ndarray:
    """Integer positions of Morton codes: (N,) uint64 -> (N, 3) uint32 (inverse of encode)."""
    c = np.asarray(codes, dtype=np.uint64)
    out = np.empty((c.shape[0], 3), np.uint32)
    for axis in range(3):
        out[:, axis] = _compact(c >> np.uint64(axis))
    return out
