"""Byte layout of the color codec's chunk payloads (spec/FORMAT.md §12), both directions.

Chunk types (all critical):

    base      SCNE  scene header: counts, SH degrees, position grid, value grid
              GEOM  quantized positions (the geometry coder's payload)
              OUTL  far outliers: exact float32 positions of Gaussians outside the grid
    color     CHYP  color hyperprior: channel mask + integer network (optional)
              SHDC  SH degree-0 coefficients       (float stream, 3 channels)
              SHBA/SHBB/SHBC  SH bands 1/2/3        (float stream, 9/15/21 channels)
              OPAC  opacity logits                  (float stream, 1 channel)
              SCAL  log-scales                      (float stream, 3 channels)
              ROTN  rotations: dropped-component categorical stream + float stream (3)
    semantic  SEMF  semantic features: names + float stream (S channels)
              SEML  integer labels: residual stream with step 1 (lossless)
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter

STREAM_CHUNKS = {"dc": "SHDC", "rest1": "SHBA", "rest2": "SHBB", "rest3": "SHBC",
                 "opacity": "OPAC", "scale": "SCAL", "rot": "ROTN"}
CHUNK_STREAMS = {v: k for k, v in STREAM_CHUNKS.items()}
STREAM_CHANNELS = {"dc": 3, "rest1": 9, "rest2": 15, "rest3": 21, "opacity": 1, "scale": 3,
                   "rot": 3}
#: Most Gaussians a file may declare (a decoder limit).
MAX_GAUSSIANS = 1 << 28
MAX_SEMANTIC_CHANNELS = 256
#: A float stream's channel_count is one byte (FORMAT §12.8): SEMF carries at most 255.
MAX_FLOAT_STREAM_CHANNELS = 255
#: Longest semantic channel name, in UTF-8 bytes (FORMAT §12.16).
MAX_NAME_BYTES = 256


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


def check_finite(values: np.ndarray, chunk: str) -> None:
    """FormatError when a decoded stream holds a non-finite value (float32 overflow)."""
    if values.size and not np.all(np.isfinite(values)):
        raise FormatError("decoded values overflow float32", chunk=chunk)


def names_to_bytes(out: ByteWriter, names: tuple[str, ...]) -> None:
    """Append varint S and S UTF-8 byte strings."""
    out.varint(len(names))
    for name in names:
        out.byte_string(name.encode("utf-8"))


#: A semantic channel name (FORMAT §12.16): a PLY property name a 3DGS reader keeps as a
#: semantic channel (the prefix), ASCII letters, digits and underscores only, so that it
#: cannot break a PLY header or collide with a standard 3DGS property.
SEMANTIC_NAME = re.compile(r"(sem_|ins_feat_)[A-Za-z0-9_]+")
SEMANTIC_NAME_RULE = ("sem_ or ins_feat_ followed by one or more ASCII letters, digits or "
                      "underscores, each name once")


def semantic_name_problem(name: str, earlier) -> str | None:
    """Why ``name`` cannot be a semantic channel name after the names ``earlier`` (a
    collection), or None when it can (:data:`SEMANTIC_NAME_RULE`)."""
    if not SEMANTIC_NAME.fullmatch(name):
        return (f"semantic channel name {name!r} is not a PLY-safe semantic identifier "
                f"(names are {SEMANTIC_NAME_RULE})")
    if len(name) > MAX_NAME_BYTES:
        return f"semantic channel name is {len(name)} bytes long, over {MAX_NAME_BYTES}"
    if name in earlier:
        return f"semantic channel name {name!r} appears twice"
    return None


def names_from_bytes(r: ByteReader, maximum: int) -> tuple[str, ...]:
    """Read what :func:`names_to_bytes` wrote (at most ``maximum`` names of <= 256 bytes):
    the semantic channel names of SEMF and ASEM, each checked against
    :data:`SEMANTIC_NAME_RULE` (FormatError at the offending name)."""
    count = r.varint("channel_count", maximum=maximum)
    names = []
    for _ in range(count):
        at = r.offset
        raw = r.byte_string("channel_name", maximum=MAX_NAME_BYTES)
        try:
            name = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise r.error("channel name is not UTF-8") from None
        problem = semantic_name_problem(name, names)
        if problem:
            raise r.error(problem, at)
        names.append(name)
    return tuple(names)
