"""The tree of a scene coded with levels of detail (FORMAT §12.22, tile index version 2).

Level 0 holds the scene's own Gaussians, split into ``2**depth`` k-d cells (leaves) by the
tiling's cut (:mod:`csgs_codec.codec.tiling`) applied to every cell down to the same depth:
the smallest depth whose cells hold at most the tile size. Level l >= 1 is the level below
with groups of about 8 neighbouring Gaussians merged into one each
(:mod:`csgs_codec.levels`), cut into the k-d cells ``3 * l`` cuts above the leaves (the root
once that reaches it): each of its tiles is the parent of the tiles of level l - 1 inside its
cell, 8 of them (fewer at the root), and holds about as many Gaussians as each of them.

Tiles are numbered coarsest level first, each level's cells in k-d order (lower half first),
so the file's coarse tiles come first in every layer and the level-0 tiles last, in the
order a file of the same tiles without levels has them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.codec.tiling import _cut
from csgs_codec.errors import InputError

#: Tile size (leaf Gaussians at most) of a scene coded with levels when none is given.
LOD_TILE_SIZE = 65_536
#: Most levels a file may have (tile index version 2: levels 0..15).
MAX_LEVELS = 16
#: k-d cuts between a tile and its parent: 2**3 = 8 children.
CUTS_PER_LEVEL = 3


def leaf_depth(count: int, tile_size: int) -> int:
    """The smallest depth d whose k-d cells hold at most ``tile_size`` of ``count`` points
    (a cell at depth d holds floor or ceil of count / 2**d)."""
    depth = 0
    while -(-count // (1 << depth)) > tile_size:
        depth += 1
    return depth


def split_to_depth(positions: np.ndarray, depth: int) -> list[np.ndarray]:
    """The ``2**depth`` k-d cells of ``positions`` (N, 3), every cell cut ``depth`` times:
    increasing int64 row arrays in k-d order (lower half first)."""
    cells = [np.arange(len(positions), dtype=np.int64)]
    p = np.asarray(positions)
    for _ in range(depth):
        halves = []
        for rows in cells:
            halves += list(_cut(p, rows)) if len(rows) > 1 else [rows, rows[:0]]
        cells = halves
    return cells


@dataclass(frozen=True)
class LevelTree:
    """The tiles of a scene with ``levels`` levels whose leaves are ``leaves`` (level 0's
    cells: ``2**depth`` increasing row arrays into the scene, in k-d order)."""

    leaves: tuple[np.ndarray, ...]
    depth: int
    levels: int

    @classmethod
    def build(cls, positions: np.ndarray, tile_size: int, levels: int) -> LevelTree:
        """The tree of a scene at ``positions`` (N, 3) with leaves of at most ``tile_size``.

        Raises:
            InputError: ``levels`` outside 1..:data:`MAX_LEVELS`, or a leaf would be empty
                (a tile size below half the scene's points per leaf cannot happen; fewer
                points than leaves can).
        """
        if isinstance(levels, bool) or not isinstance(levels, int) or not (
                1 <= levels <= MAX_LEVELS):
            raise InputError(f"levels must be an integer in 1..{MAX_LEVELS}, got {levels!r}",
                             property="levels")
        depth = leaf_depth(len(positions), tile_size)
        leaves = tuple(split_to_depth(positions, depth))
        if any(len(rows) == 0 for rows in leaves):
            raise InputError(f"{len(positions):,} Gaussians are too few for tiles of "
                             f"{tile_size:,}", property="tile_size")
        return cls(leaves, depth, levels)

    def node_depth(self, level: int) -> int:
        """The k-d depth of level ``level``'s cells."""
        return max(self.depth - CUTS_PER_LEVEL * level, 0)

    def node_count(self, level: int) -> int:
        """Tiles of level ``level``."""
        return 1 << self.node_depth(level)

    def first_tile(self, level: int) -> int:
        """The number of level ``level``'s first tile (coarser levels are numbered first)."""
        return sum(self.node_count(k) for k in range(level + 1, self.levels))

    def parent(self, level: int, node: int) -> int | None:
        """The tile number of node ``node`` of level ``level``'s parent (None at the top)."""
        if level + 1 >= self.levels:
            return None
        shift = self.node_depth(level) - self.node_depth(level + 1)
        return self.first_tile(level + 1) + (node >> shift)

    def children(self, level: int) -> np.ndarray:
        """(node_count(level - 1),) the node of level ``level`` each node of the level
        below belongs to."""
        shift = self.node_depth(level - 1) - self.node_depth(level)
        return np.arange(self.node_count(level - 1)) >> shift

    @property
    def tile_count(self) -> int:
        """Tiles in all levels."""
        return self.first_tile(-1)
