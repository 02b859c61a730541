"""The ``TIDX`` chunk: how a scene is split into spatial tiles (FORMAT §12.22).

A multi-tile file starts with one ``TIDX`` chunk (TOC entry 0, tile 0) listing, for every
tile 0..T-1, its Gaussian count and the box its decoded positions lie in, so a reader picks
the tiles a region needs from the TOC and this one chunk, without decoding any tile.
A single-tile file has no ``TIDX``.

Version 2 adds levels of detail: every tile has a level (0: the scene's own Gaussians;
l > 0: a coarser version of the tiles of level l - 1 whose parent it is) and a parent of
the next level up (none at the top level), so each level is the whole scene once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.format.primitives import ByteReader, ByteWriter

VERSION = 1
#: The version of an index with levels of detail.
LEVELS_VERSION = 2
#: Most levels an index may have (levels 0..15).
MAX_LEVELS = 16
#: Most tiles a file may list (a TOC holds at most 65,535 chunks; a tile needs several).
MAX_TILES = 65_535
#: Most Gaussians one tile may hold (the reference decoder's per-scene limit, FORMAT §10.1).
MAX_TILE_GAUSSIANS = 1 << 24
#: Bytes a tile's entry takes at least: a 1-byte count and six float32 bounds.
MIN_ENTRY_BYTES = 25
#: ... and in version 2, with a 1-byte level and a 1-byte parent.
MIN_LEVEL_ENTRY_BYTES = 27


@dataclass(frozen=True)
class TileInfo:
    """One tile of the index: ``count`` Gaussians whose decoded positions lie in the box
    ``lower`` .. ``upper`` ((3,) float32 world units each, inclusive), at ``level`` of detail
    (0: the scene's own Gaussians) with ``parent``, the tile of the next level up that it
    refines (None at the top level and in a file without levels)."""

    count: int
    lower: tuple[float, float, float]
    upper: tuple[float, float, float]
    level: int = 0
    parent: int | None = None

    def intersects(self, lower, upper) -> bool:
        """True when the tile's box meets the closed box ``lower`` .. ``upper`` ((3,) each)."""
        return all(self.lower[a] <= upper[a] and lower[a] <= self.upper[a] for a in range(3))


@dataclass(frozen=True)
class TileIndex:
    """The ``TIDX`` payload: one :class:`TileInfo` per tile, tile ``i`` at position ``i``."""

    tiles: tuple[TileInfo, ...]

    @property
    def count(self) -> int:
        """Gaussians in all tiles together."""
        return sum(t.count for t in self.tiles)

    @property
    def levels(self) -> int:
        """Levels of detail: 1 + the highest tile level (1 in a file without levels)."""
        return 1 + max(t.level for t in self.tiles)

    def level_tiles(self, level: int) -> list[int]:
        """Numbers of the tiles of ``level``, increasing (level 0: the whole scene)."""
        return [i for i, t in enumerate(self.tiles) if t.level == level]

    def children(self, number: int) -> list[int]:
        """Numbers of the tiles whose parent is tile ``number``, increasing."""
        return [i for i, t in enumerate(self.tiles) if t.parent == number]

    def select(self, lower, upper) -> list[int]:
        """Numbers of the tiles whose boxes meet the closed box ``lower`` .. ``upper``."""
        return [i for i, t in enumerate(self.tiles) if t.intersects(lower, upper)]

    def to_bytes(self) -> bytes:
        """The chunk payload: version 1, or version 2 when a tile has a level above 0."""
        leveled = self.levels > 1
        out = ByteWriter()
        out.fixed("u8", LEVELS_VERSION if leveled else VERSION)
        out.varint(len(self.tiles))
        for tile in self.tiles:
            out.varint(tile.count)
            out.array(np.asarray(tile.lower + tile.upper, np.float32), "<f4")
            if leveled:
                out.fixed("u8", tile.level)
                out.varint(0 if tile.parent is None else tile.parent + 1)
        return out.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, base_offset: int = 0) -> TileIndex:
        """Parse and validate a payload.

        Raises:
            FormatError: an unknown version, no tile or more than :data:`MAX_TILES`, more
                tiles than the payload can hold, a tile of 0 or more than 2^24 Gaussians,
                a bound that is not finite or a lower bound above its upper one, trailing
                bytes; in version 2 a level above 15, or a tree that is not one (see
                :func:`_check_tree`).
        """
        r = ByteReader(data, base_offset=base_offset, chunk="TIDX")
        version = r.fixed("u8", "version")
        if version not in (VERSION, LEVELS_VERSION):
            raise r.error(f"unknown tile index version {version}", at=r.offset - 1)
        leveled = version == LEVELS_VERSION
        at = r.offset
        count = r.varint("tile_count", maximum=MAX_TILES)
        entry_bytes = MIN_LEVEL_ENTRY_BYTES if leveled else MIN_ENTRY_BYTES
        if count < 1 or count > r.remaining // entry_bytes:
            raise r.error(f"tile_count {count} is 0 or more than the {r.remaining} bytes "
                          "after it hold", at=at)
        tiles, links = [], []
        for i in range(count):
            at = r.offset
            n = r.varint("gaussian_count", maximum=MAX_TILE_GAUSSIANS)
            if n < 1:
                raise r.error(f"tile {i} holds no Gaussian", at=at)
            box_at = r.offset
            box = r.array(6, "<f4", "bounds").astype(np.float32)
            if not np.all(np.isfinite(box)) or np.any(box[:3] > box[3:]):
                raise r.error(f"tile {i}: bounds {box.tolist()} are not finite or lower > "
                              "upper", at=box_at)
            level, parent = 0, None
            if leveled:
                level_at = r.offset
                level = r.fixed("u8", "level")
                if level >= MAX_LEVELS:
                    raise r.error(f"tile {i}: level {level} is above {MAX_LEVELS - 1}",
                                  at=level_at)
                link_at = r.offset
                link = r.varint("parent", maximum=MAX_TILES)
                parent = None if link == 0 else link - 1
                links.append((level_at, link_at))
            tiles.append(TileInfo(n, tuple(float(v) for v in box[:3]),
                                  tuple(float(v) for v in box[3:]), level, parent))
        r.expect_end("the tile index")
        if leveled:
            _check_tree(r, tiles, links)
        return cls(tuple(tiles))


def _check_tree(r: ByteReader, tiles: list[TileInfo], links: list[tuple[int, int]]) -> None:
    """FormatError unless the tiles form a tree of levels (FORMAT §12.22): L = 1 + the
    highest level is at least 2; a tile of the top level has no parent, every other tile a
    parent of the level above it; every tile above level 0 is some tile's parent."""
    top = max(t.level for t in tiles)
    if top == 0:
        raise r.error("a version-2 tile index whose tiles are all of level 0",
                      at=links[0][0])
    has_child = [False] * len(tiles)
    for i, (tile, (_, link_at)) in enumerate(zip(tiles, links)):
        if tile.level == top:
            if tile.parent is not None:
                raise r.error(f"tile {i} is of the top level {top} and has a parent",
                              at=link_at)
            continue
        if tile.parent is None:
            raise r.error(f"tile {i} of level {tile.level} has no parent (only the top "
                          f"level {top} has none)", at=link_at)
        if tile.parent >= len(tiles) or tiles[tile.parent].level != tile.level + 1:
            raise r.error(f"tile {i} of level {tile.level}: parent {tile.parent} is not a "
                          f"tile of level {tile.level + 1}", at=link_at)
        has_child[tile.parent] = True
    for i, tile in enumerate(tiles):
        if tile.level > 0 and not has_child[i]:
            raise r.error(f"tile {i} of level {tile.level} is no tile's parent",
                          at=links[i][0])


def tile_info(positions: np.ndarray) -> TileInfo:
    """The index entry of a tile whose decoded positions are ``positions`` (N, 3) float32."""
    p = np.asarray(positions, np.float32)
    return TileInfo(len(p), tuple(float(v) for v in p.min(axis=0)),
                    tuple(float(v) for v in p.max(axis=0)))
