"""The ``TIDX`` chunk: how a scene is split into spatial tiles (FORMAT §12.22).

A multi-tile file starts with one ``TIDX`` chunk (TOC entry 0, tile 0) listing, for every
tile 0..T-1, its Gaussian count and the box its decoded positions lie in, so a reader picks
the tiles a region needs from the TOC and this one chunk, without decoding any tile.
A single-tile file has no ``TIDX``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.format.primitives import ByteReader, ByteWriter

VERSION = 1
#: Most tiles a file may list (a TOC holds at most 65,535 chunks; a tile needs several).
MAX_TILES = 65_535
#: Most Gaussians one tile may hold (the reference decoder's per-scene limit, FORMAT §10.1).
MAX_TILE_GAUSSIANS = 1 << 24
#: Bytes a tile's entry takes at least: a 1-byte count and six float32 bounds.
MIN_ENTRY_BYTES = 25


@dataclass(frozen=True)
class TileInfo:
    """One tile of the index: ``count`` Gaussians whose decoded positions lie in the box
    ``lower`` .. ``upper`` ((3,) float32 world units each, inclusive)."""

    count: int
    lower: tuple[float, float, float]
    upper: tuple[float, float, float]

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

    def select(self, lower, upper) -> list[int]:
        """Numbers of the tiles whose boxes meet the closed box ``lower`` .. ``upper``."""
        return [i for i, t in enumerate(self.tiles) if t.intersects(lower, upper)]

    def to_bytes(self) -> bytes:
        """The chunk payload."""
        out = ByteWriter()
        out.fixed("u8", VERSION)
        out.varint(len(self.tiles))
        for tile in self.tiles:
            out.varint(tile.count)
            out.array(np.asarray(tile.lower + tile.upper, np.float32), "<f4")
        return out.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, base_offset: int = 0) -> TileIndex:
        """Parse and validate a payload.

        Raises:
            FormatError: an unknown version, no tile or more than :data:`MAX_TILES`, more
                tiles than the payload can hold, a tile of 0 or more than 2^24 Gaussians,
                a bound that is not finite or a lower bound above its upper one, or
                trailing bytes.
        """
        r = ByteReader(data, base_offset=base_offset, chunk="TIDX")
        version = r.fixed("u8", "version")
        if version != VERSION:
            raise r.error(f"unknown tile index version {version}", at=r.offset - 1)
        at = r.offset
        count = r.varint("tile_count", maximum=MAX_TILES)
        if count < 1 or count > r.remaining // MIN_ENTRY_BYTES:
            raise r.error(f"tile_count {count} is 0 or more than the {r.remaining} bytes "
                          "after it hold", at=at)
        tiles = []
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
            tiles.append(TileInfo(n, tuple(float(v) for v in box[:3]),
                                  tuple(float(v) for v in box[3:])))
        r.expect_end("the tile index")
        return cls(tuple(tiles))


def tile_info(positions: np.ndarray) -> TileInfo:
    """The index entry of a tile whose decoded positions are ``positions`` (N, 3) float32."""
    p = np.asarray(positions, np.float32)
    return TileInfo(len(p), tuple(float(v) for v in p.min(axis=0)),
                    tuple(float(v) for v in p.max(axis=0)))
