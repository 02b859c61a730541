"""Encoder side: the voxel grid of anchor positions (origin, voxel size, integer cells)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.entropy.morton import MAX_BITS
from csgs_codec.errors import InputError

#: Cells per axis of the fallback grid for positions that are not on a voxel grid.
FALLBACK_BITS = 16
#: Positions count as on the grid when every one is within this share of a voxel of its cell.
ON_GRID_TOLERANCE = 0.05


@dataclass(frozen=True)
class AnchorGrid:
    """Anchor cells: position = origin + cell * voxel_size (float64, then float32).

    Attributes:
        origin: (3,) float64 world position of cell (0, 0, 0).
        voxel_size: cell edge, world units.
        cells: (M, 3) int64 cells, each in [0, 2^bits).
        bits: bits per axis (0..21).
    """

    origin: np.ndarray
    voxel_size: float
    cells: np.ndarray
    bits: int

    def positions(self, cells: np.ndarray | None = None) -> np.ndarray:
        """(M, 3) float32 positions of ``cells`` (default: this grid's cells)."""
        c = self.cells if cells is None else cells
        return dequantize(c, self.origin, self.voxel_size)


def dequantize(cells: np.ndarray, origin, voxel_size: float) -> np.ndarray:
    """(M, 3) integer cells -> (M, 3) float32 ``origin + cell * voxel_size`` (float64 first).

    Values beyond the float32 range become inf (no warning); the decoder refuses them.
    """
    values = (np.asarray(origin, np.float64)[None, :]
              + np.asarray(cells, np.float64) * float(voxel_size))
    with np.errstate(over="ignore"):
        return values.astype(np.float32)


def _cells(p: np.ndarray, origin: np.ndarray, voxel: float) -> np.ndarray:
    return np.rint((p - origin) / voxel).astype(np.int64)


def _bits(cells: np.ndarray) -> int:
    top = int(cells.max()) if cells.size else 0
    return max(top, 0).bit_length()


def _infer_voxel(p: np.ndarray, origin: np.ndarray) -> float | None:
    """The voxel size positions sit on, or None when they are not on a grid."""
    gaps = []
    for d in range(3):
        diff = np.diff(np.unique(p[:, d]))
        if diff.size:
            gaps.append(diff.min())
    if not gaps or min(gaps) <= 0:
        return None
    voxel = float(min(gaps))
    cells = _cells(p, origin, voxel)
    norm = float((cells.astype(np.float64) ** 2).sum())
    if norm > 0:  # least-squares voxel size through the rounded cells
        voxel = float((cells * (p - origin)).sum() / norm)
    cells = _cells(p, origin, voxel)
    if np.abs(origin + cells * voxel - p).max() > ON_GRID_TOLERANCE * voxel:
        return None
    if _bits(cells) > MAX_BITS:
        return None
    return voxel


def anchor_grid(positions: np.ndarray, voxel_size: float | None = None) -> AnchorGrid:
    """Put (M, 3) anchor positions on a voxel grid.

    With ``voxel_size`` None the grid is inferred: the smallest coordinate gap, refined by
    least squares, when every anchor then lies within 5% of a voxel of its cell (Scaffold-GS
    anchors are voxel centres); otherwise a 2^16-cell grid over the extent (positions lossy
    by at most half a cell per axis).

    Raises:
        InputError: a given voxel size that is not positive or needs more than 21 bits.
    """
    p = np.asarray(positions, dtype=np.float64)
    origin = p.min(axis=0) if len(p) else np.zeros(3)
    if voxel_size is not None:
        if not (np.isfinite(voxel_size) and voxel_size > 0):
            raise InputError(f"voxel_size must be positive, got {voxel_size}",
                             property="voxel_size")
        voxel = float(voxel_size)
    else:
        voxel = _infer_voxel(p, origin) if len(p) > 1 else 1.0
        if voxel is None:
            extent = float((p.max(axis=0) - origin).max())
            voxel = extent / ((1 << FALLBACK_BITS) - 1) if extent > 0 else 1.0
    cells = _cells(p, origin, voxel)
    bits = _bits(cells)
    if bits > MAX_BITS:
        raise InputError(f"voxel_size {voxel} needs {bits} bits per axis (at most "
                         f"{MAX_BITS})", property="voxel_size")
    return AnchorGrid(origin, voxel, cells, bits)
