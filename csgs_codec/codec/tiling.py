"""Splitting a scene into spatial tiles: k-d cells of at most ``tile_size`` Gaussians.

A cell of more than ``tile_size`` Gaussians is cut in two halves of equal count (the lower
half gets the extra one) along the longest side of its points' robust box (the 1-99
percentile box, so far outliers never choose the axis); the lower half's tiles come first.
Points are ranked along the axis by (coordinate, input index), so ties split the same way
on every machine. The cut is a plane at the median coordinate: the outermost cells are
unbounded, and a far outlier belongs to the cell whose half-spaces hold it, whichever that
is. Every tile's Gaussians then share one position-grid cell size (that of the whole scene,
:class:`~csgs_codec.scene.position_grid.PositionGrid`), so a tiled encode quantizes every
point as the untiled one does, each tile with its own grid origin and bits.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.position_grid import PositionGrid

#: Scenes with more Gaussians than this are tiled when no tile size is given.
AUTO_TILE_THRESHOLD = 2_000_000
#: Tile size of such scenes.
DEFAULT_TILE_SIZE = 1_000_000
#: Largest tile size (the decoder's limit on one scene, FORMAT §10.1).
MAX_TILE_SIZE = 1 << 24
#: Percentile of the robust box that picks a cell's cut axis.
AXIS_PERCENTILE = 1.0


def check_tile_size(tile_size: int | None) -> None:
    """InputError unless ``tile_size`` is None (automatic) or an int in 1..2^24."""
    if tile_size is None:
        return
    if isinstance(tile_size, bool) or not isinstance(tile_size, int | np.integer) or not (
            1 <= tile_size <= MAX_TILE_SIZE):
        raise InputError(f"tile size must be an integer in 1..{MAX_TILE_SIZE:,}, got "
                         f"{tile_size!r}", property="tile_size")


def effective_tile_size(count: int, tile_size: int | None) -> int:
    """The tile size a scene of ``count`` Gaussians is split with: ``tile_size`` when given,
    else :data:`DEFAULT_TILE_SIZE` above :data:`AUTO_TILE_THRESHOLD` Gaussians, else
    ``count`` (one tile)."""
    if tile_size is not None:
        return int(tile_size)
    return DEFAULT_TILE_SIZE if count > AUTO_TILE_THRESHOLD else max(count, 1)


def split_tiles(positions: np.ndarray, tile_size: int) -> list[np.ndarray]:
    """The tiles of ``positions`` (N, 3): a list of increasing int64 index arrays, each of
    at most ``tile_size`` and at least ``tile_size // 2`` points (one tile when N <=
    ``tile_size``), in tile order."""
    p = np.asarray(positions)
    tiles: list[np.ndarray] = []
    stack = [np.arange(len(p), dtype=np.int64)]
    while stack:
        rows = stack.pop()
        if len(rows) <= tile_size:
            tiles.append(rows)
            continue
        low, high = _cut(p, rows)
        stack += [high, low]  # low is popped first: depth first, lower half first
    return tiles


def _cut(p: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two halves (increasing indices each) of the cell ``rows``."""
    cell = p[rows].astype(np.float64)
    lo = np.percentile(cell, AXIS_PERCENTILE, axis=0, method="higher")
    hi = np.percentile(cell, 100 - AXIS_PERCENTILE, axis=0, method="lower")
    axis = int(np.argmax(hi - lo))  # the first longest side on a tie
    rank = np.lexsort((rows, cell[:, axis]))  # coordinate, then input index
    half = (len(rows) + 1) // 2
    return np.sort(rows[rank[:half]]), np.sort(rows[rank[half:]])


def tile_grid(cells: np.ndarray, grid: PositionGrid) -> tuple[PositionGrid, np.ndarray]:
    """The grid of one tile and its points' cells on it.

    Args:
        cells: (M, 3) int64 cells of the tile's points on the whole scene's ``grid`` (the
            points inside that grid only).
        grid: the whole scene's grid.

    Returns:
        (grid with the same cell size, origin at the tile's lowest cell and the fewest bits
        that hold its span; (M, 3) cells on it).
    """
    if not len(cells):
        return PositionGrid(grid.origin, grid.cell, 1), cells
    lo = cells.min(axis=0)
    local = cells - lo
    bits = max(1, int(local.max()).bit_length())
    origin = tuple(float(o + float(k) * grid.cell) for o, k in zip(grid.origin, lo))
    return PositionGrid(origin, grid.cell, bits), local
