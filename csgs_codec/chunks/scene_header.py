"""The scene header chunk SCNE (FORMAT §12.2), both directions: counts, SH degrees, the
position grid and the far points' count."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Most Gaussians a file may declare (a decoder limit).
MAX_GAUSSIANS = 1 << 28


@dataclass(frozen=True)
class SceneHeader:
    """The SCNE payload.

    Attributes:
        count: Gaussians N (grid points plus far outliers).
        sh_degree_stored: SH degree of the decoded scene (0..3).
        sh_degree_coded: SH bands that have a stream (0..sh_degree_stored).
        quality: the preset used (1..9), informational.
        grid_origin: (x, y, z) float64 world units; grid_cell: float64 > 0; grid_bits: 0..21.
        far_count: Gaussians in the OUTL chunk (<= count).
    """

    count: int
    sh_degree_stored: int
    sh_degree_coded: int
    quality: int
    grid_origin: tuple[float, float, float]
    grid_cell: float
    grid_bits: int
    far_count: int

    def to_bytes(self) -> bytes:
        """The SCNE payload bytes."""
        out = ByteWriter()
        out.varint(self.count)
        out.fixed("u8", self.sh_degree_stored)
        out.fixed("u8", self.sh_degree_coded)
        out.fixed("u8", self.quality)
        for v in self.grid_origin:
            out.fixed("f64", v)
        out.fixed("f64", self.grid_cell)
        out.fixed("u8", self.grid_bits)
        out.varint(self.far_count)
        return out.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, base_offset: int = 0) -> SceneHeader:
        """Parse and validate a SCNE payload.

        Raises:
            FormatError: a field out of range, truncation or trailing bytes.
        """
        r = ByteReader(data, base_offset=base_offset, chunk="SCNE")
        count = r.varint("gaussian_count", maximum=MAX_GAUSSIANS)
        stored = r.fixed("u8", "sh_degree_stored")
        coded = r.fixed("u8", "sh_degree_coded")
        quality = r.fixed("u8", "quality")
        origin = tuple(r.fixed("f64", f"grid_origin_{a}") for a in "xyz")
        cell = r.fixed("f64", "grid_cell")
        bits = r.fixed("u8", "grid_bits")
        far = r.varint("far_count", maximum=count)
        r.expect_end("the scene header")
        if stored > 3 or coded > stored:
            raise r.error(f"SH degrees stored {stored} / coded {coded} are invalid")
        if not all(np.isfinite(origin)) or not (np.isfinite(cell) and cell > 0):
            raise r.error("grid origin and cell must be finite, cell > 0")
        if bits > 21:
            raise r.error(f"grid_bits {bits} exceeds 21")
        return cls(count, stored, coded, quality, origin, cell, bits, far)
