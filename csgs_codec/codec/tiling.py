"""Splitting a scene into spatial tiles: k-d cells of at most ``tile_size`` Gaussians.

A cell of more than ``tile_size`` Gaussians is cut in two halves of equal count (the lower
half gets the extra one) along the longest side of its points' robust box (the 1-99
percentile box, so far outliers never choose the axis); the lower half's tiles come first.
Points are ranked along the axis by (coordinate, input index), so ties split the same way
on every machine. The cut is a plane at the median coordinate: the outermost cells are
unbounded, and a far outlier belongs to the cell whose half-spaces hold it, whichever that
is. Every tile's Gaussians then share one position-grid cell size (that of the whole scene,
:class:`~csgs_codec.attributes.position_grid.PositionGrid`), so a tiled encode quantizes every
point as the untiled one does, each tile with its own grid origin and bits.

Limits (issue #29): every tile costs its own chunks, headers and coder set-up, so a tile
size below :data:`MIN_TILE_SIZE` (1,000 Gaussians) is refused, except that a scene may always
be cut into about 16 tiles (a tile size down to a 16th of the scene: small test scenes in a
few tiles); and a tiling must fit the file's chunk limit (:data:`MAX_ENCODED_TILES`).
"""

from __future__ import annotations

import math

import numpy as np

from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.errors import InputError
from csgs_codec.format.layout import MAX_CHUNKS

#: Scenes with more Gaussians than this are tiled when no tile size is given.
AUTO_TILE_THRESHOLD = 2_000_000
#: Tile size of such scenes.
DEFAULT_TILE_SIZE = 1_000_000
#: Largest tile size (the decoder's limit on one scene, FORMAT §10.1).
MAX_TILE_SIZE = 1 << 24
#: Smallest tile size of a scene of 16,000 Gaussians or more.
MIN_TILE_SIZE = 1_000
#: A smaller scene may use tiles down to this fraction (1/N) of it: about 16 tiles.
SMALL_SCENE_TILES = 16
#: Most chunk types one tile can hold (SCNE .. SEML, vdis and a fill), FORMAT §12.1.
CHUNKS_PER_TILE = 16
#: Most tiles an encoder writes: their chunks and the TIDX fit MAX_CHUNKS (65,535).
MAX_ENCODED_TILES = (MAX_CHUNKS - 1) // CHUNKS_PER_TILE
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
    ``count`` (one tile).

    Raises:
        InputError: the tiling is refused (see :func:`check_tiling`).
    """
    if tile_size is not None:
        size = int(tile_size)
    else:
        size = DEFAULT_TILE_SIZE if count > AUTO_TILE_THRESHOLD else max(count, 1)
    check_tiling(count, size)
    return size


def smallest_tile_size(count: int) -> int:
    """The smallest tile size a scene of ``count`` Gaussians may be split with:
    :data:`MIN_TILE_SIZE`, or a :data:`SMALL_SCENE_TILES`-th of a smaller scene."""
    return max(min(MIN_TILE_SIZE, math.ceil(count / SMALL_SCENE_TILES)), 1)


def tile_count(count: int, tile_size: int) -> int:
    """How many tiles :func:`split_tiles` cuts ``count`` points into (it depends on the
    counts alone: a cell of n > ``tile_size`` points becomes cells of ceil(n/2) and
    floor(n/2)), computed without the points."""
    cells, tiles = {count: 1}, 0
    while cells:
        halves: dict[int, int] = {}
        for n, times in cells.items():
            if n <= tile_size:
                tiles += times
                continue
            for half in ((n + 1) // 2, n // 2):
                halves[half] = halves.get(half, 0) + times
        cells = halves
    return tiles


def check_tiling(count: int, tile_size: int) -> None:
    """Refuse to split ``count`` Gaussians into tiles of at most ``tile_size`` when the tiles
    would be too small or too many (a scene that fits one tile is never refused).

    Raises:
        InputError: ``tile_size`` is below :func:`smallest_tile_size`, or the tiling has more
            than :data:`MAX_ENCODED_TILES` tiles; the message gives the smallest tile size
            that would do.
    """
    if count <= tile_size:
        return
    minimum = smallest_tile_size(count)
    if tile_size < minimum:
        small = (f"; a scene of fewer than {MIN_TILE_SIZE * SMALL_SCENE_TILES:,} may use a "
                 f"{SMALL_SCENE_TILES}th of itself, {minimum:,} for these {count:,}"
                 if minimum < MIN_TILE_SIZE else "")
        raise InputError(f"tile size {tile_size:,} is too small: the minimum is "
                         f"{MIN_TILE_SIZE:,} Gaussians{small}", property="tile_size")
    tiles = tile_count(count, tile_size)
    if tiles > MAX_ENCODED_TILES:
        raise InputError(f"tile size {tile_size:,} cuts these {count:,} Gaussians into "
                         f"{tiles:,} tiles, more than the {MAX_ENCODED_TILES:,} a file holds; "
                         f"the smallest tile size that fits is "
                         f"{_fewest_tiles_size(count, tile_size):,}", property="tile_size")


def _fewest_tiles_size(count: int, tile_size: int) -> int:
    """The smallest tile size above ``tile_size`` that cuts ``count`` points into at most
    :data:`MAX_ENCODED_TILES` tiles (tile_count falls as the size grows)."""
    low, high = tile_size, count
    while high - low > 1:
        middle = (low + high) // 2
        if tile_count(count, middle) > MAX_ENCODED_TILES:
            low = middle
        else:
            high = middle
    return high


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
