"""The encoder's plan for Gaussians outside the position grid ("far points"); their chunks'
bytes, both directions, are :mod:`csgs_codec.chunks.far_points`.

Up to :data:`EXACT_FAR_LIMIT` far points are kept exactly (OUTL, 12 bytes each: a handful of
floaters costs nothing worth saving). More are coded with relative precision (OUTQ,
:mod:`csgs_codec.attributes.far_positions`) with ``b = position_bits + 1`` mantissa bits, so a far
point errs by at most ``2^-position_bits`` times its Chebyshev distance from the grid's
centre per axis (plus float32 rounding): the angular precision a grid cell has at the dense
core's edge. Points that scheme cannot represent stay exact. The encoder warns
(:class:`~csgs_codec.errors.CsgsWarning`) whenever it codes points apart.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from csgs_codec.attributes.far_positions import MAX_MANTISSA_BITS, dequantize_far, quantize_far
from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.chunks.far_points import exact_far_payload, relative_far_payload
from csgs_codec.errors import CsgsWarning
from csgs_codec.format import Chunk

#: At most this many far points are kept as exact float32 (OUTL) without trying OUTQ.
EXACT_FAR_LIMIT = 16


@dataclass
class FarPoints:
    """Far points in decoded order: ``order`` (F,) int64 indices into the scene (OUTQ points
    first, then OUTL), ``positions`` (F, 3) float32 as decoded, ``chunks`` to append to the
    base layer, and how many are coded with relative precision / exactly."""

    order: np.ndarray
    positions: np.ndarray
    chunks: list[Chunk] = field(default_factory=list)
    relative: int = 0
    exact: int = 0


def plan_far_points(positions: np.ndarray, far_idx: np.ndarray, grid: PositionGrid,
                    position_bits: int) -> FarPoints:
    """Code the Gaussians ``far_idx`` (F,) of ``positions`` (N, 3) float32 apart.

    Args:
        positions: the scene's (N, 3) float32 world positions.
        far_idx: indices of the points outside ``grid``, increasing.
        grid: the fitted position grid (its centre is the relative coder's centre).
        position_bits: the preset's bits per axis over the dense core.
    """
    far_idx = np.asarray(far_idx, np.int64)
    if not len(far_idx):
        return FarPoints(far_idx, np.zeros((0, 3), np.float32))
    exact_mask = np.ones(len(far_idx), dtype=bool)
    chunks = []
    relative_positions = np.zeros((0, 3), np.float32)
    if len(far_idx) > EXACT_FAR_LIMIT:
        bits = min(position_bits + 1, MAX_MANTISSA_BITS)
        exps, mants, ok = quantize_far(positions[far_idx], grid.centre, bits)
        if ok.any():
            exact_mask = ~ok
            chunks.append(Chunk("OUTQ", "base", relative_far_payload(grid.centre, bits, exps[ok],
                                                             mants[ok])))
            relative_positions = dequantize_far(grid.centre, bits, exps[ok], mants[ok])
    exact_idx = far_idx[exact_mask]
    if len(exact_idx):
        chunks.append(Chunk("OUTL", "base", exact_far_payload(positions[exact_idx])))
    relative = len(far_idx) - len(exact_idx)
    share = 100.0 * len(far_idx) / len(positions)
    how = [f"{len(exact_idx)} exactly (float32)"] if len(exact_idx) else []
    if relative:
        how.insert(0, f"{relative} with relative precision (error <= 2^-{position_bits} x "
                      "their distance from the core's centre per axis)")
    warnings.warn(
        f"{len(far_idx)} Gaussians ({share:.2f}%) lie outside the position grid of the "
        f"scene's dense core and are coded apart: {' and '.join(how)}", CsgsWarning,
        stacklevel=4)
    return FarPoints(np.concatenate([far_idx[~exact_mask], exact_idx]),
                     np.concatenate([relative_positions,
                                     positions[exact_idx].astype(np.float32)]),
                     chunks, relative, len(exact_idx))

