"""Byte layout of the colour codec's chunk payloads (spec/FORMAT.md §12), both directions.

Chunk types (all critical):

    base      SCNE  scene header: counts, SH degrees, position grid, value grid
              GEOM  quantized positions (the geometry coder's payload)
              OUTL  far outliers: exact float32 positions of Gaussians outside the grid
    color     SHDC  SH degree-0 coefficients       (float stream, 3 channels)
              SHBA/SHBB/SHBC  SH bands 1/2/3        (float stream, 9/15/21 channels)
              OPAC  opacity logits                  (float stream, 1 channel)
              SCAL  log-scales                      (float stream, 3 channels)
              ROTN  rotations: dropped-component categorical stream + float stream (3)
    semantic  SEMF  semantic features: names + float stream (S channels)
              SEML  integer labels: residual stream with step 1 (lossless)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.entropy.residual import (
    STEP_COUNT,
    decode_residuals,
    encode_symbols,
    from_grid,
    quantize,
    reconstruct,
    step_index,
    to_grid,
)
from csgs_codec.entropy.table_choice import best_table
from csgs_codec.entropy.tables import gaussian_family
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter

STREAM_CHUNKS = {"dc": "SHDC", "rest1": "SHBA", "rest2": "SHBB", "rest3": "SHBC",
                 "opacity": "OPAC", "scale": "SCAL", "rot": "ROTN"}
CHUNK_STREAMS = {v: k for k, v in STREAM_CHUNKS.items()}
STREAM_CHANNELS = {"dc": 3, "rest1": 9, "rest2": 15, "rest3": 21, "opacity": 1, "scale": 3,
                   "rot": 3}
MODE_CONSTANT = 0
MODE_FACTORIZED = 1
#: Finest value grid: values are coded as integers in units of 2^-frac_bits.
MAX_FRAC_BITS = 24
#: Most Gaussians a file may declare (a decoder limit).
MAX_GAUSSIANS = 1 << 28
MAX_SEMANTIC_CHANNELS = 256


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


@dataclass
class CodedChannel:
    """One channel as coded: its parameters and the values the decoder will reconstruct."""

    mode: int
    reconstruction: np.ndarray  # (N,) float32
    payload_bits: int


def frac_bits_for(values: np.ndarray) -> int:
    """Finest value grid (<= 24 fractional bits) on which ``values`` stay below 2^52."""
    top = float(np.max(np.abs(values))) if values.size else 0.0
    room = 52 - int(np.ceil(np.log2(top + 1.0)))
    return int(np.clip(room, 0, MAX_FRAC_BITS))


def write_float_stream(out: ByteWriter, values: np.ndarray, step: float) -> np.ndarray:
    """Append a float stream body for ``values`` (N, C) quantized with ``step`` (value units).

    Each channel is either constant (its float32 value, no bits per Gaussian) or coded with a
    per-channel mean, the frozen Gaussian table that codes it smallest, and the step index
    nearest ``step``. Returns the (N, C) float32 values the decoder will reconstruct.
    """
    n, channels = values.shape
    f = frac_bits_for(values)
    out.varint(n)
    out.fixed("u8", channels)
    out.fixed("u8", f)
    recon = np.empty((n, channels), np.float32)
    step_idx = int(step_index(np.array([step * 2.0**f]))[0])
    for c in range(channels):
        column = values[:, c].astype(np.float32)
        if n == 0 or np.all(column == column[0]):
            value = float(column[0]) if n else 0.0
            out.fixed("u8", MODE_CONSTANT)
            out.fixed("f32", value)
            recon[:, c] = np.float32(value)
            continue
        grid = to_grid(column.astype(np.float64), f)
        mean = int(np.rint(np.median(grid)))
        mean_arr = np.full(n, mean, np.int64)
        steps = np.full(n, step_idx, np.int64)
        residuals = quantize(grid, mean_arr, steps)
        table = best_table(residuals)
        out.fixed("u8", MODE_FACTORIZED)
        out.svarint(mean)
        out.fixed("u8", table)
        out.fixed("u8", step_idx)
        out.byte_string(encode_symbols(residuals, np.full(n, table, np.int64)))
        recon[:, c] = from_grid(reconstruct(mean_arr, residuals, steps), f).astype(np.float32)
    return recon


def read_float_stream(r: ByteReader, count: int, channels: int | None = None) -> np.ndarray:
    """Read a float stream body written by :func:`write_float_stream`: (count, C) float32.

    Raises:
        FormatError: count or channel mismatch, bad mode/table/step, or a bad residual stream.
    """
    n = r.varint("count", maximum=MAX_GAUSSIANS)
    if n != count:
        raise r.error(f"stream holds {n} values, the scene has {count} Gaussians")
    c_count = r.fixed("u8", "channel_count")
    if channels is not None and c_count != channels:
        raise r.error(f"stream has {c_count} channels, expected {channels}")
    f = r.fixed("u8", "frac_bits")
    if f > MAX_FRAC_BITS:
        raise r.error(f"frac_bits {f} exceeds {MAX_FRAC_BITS}")
    out = np.empty((n, c_count), np.float32)
    tables = gaussian_family().count
    for c in range(c_count):
        mode = r.fixed("u8", "mode")
        if mode == MODE_CONSTANT:
            out[:, c] = np.float32(r.fixed("f32", "constant_value"))
            continue
        if mode != MODE_FACTORIZED:
            raise r.error(f"channel {c} has unknown mode {mode}")
        mean = r.svarint("mean")
        if abs(mean) > 1 << 53:
            raise r.error(f"mean {mean} exceeds 2^53")
        table = r.fixed("u8", "scale_index")
        step = r.fixed("u8", "step_index")
        if table >= tables or step >= STEP_COUNT:
            raise r.error(f"scale index {table} or step index {step} out of range")
        stream = r.byte_string("residual_stream")
        values = decode_residuals(stream, np.full(n, mean, np.int64), np.full(n, table, np.int64),
                                  np.full(n, step, np.int64), chunk=r.chunk,
                                  base_offset=r.offset - len(stream))
        if values.size and np.abs(values).max() >= 1 << 53:
            raise r.error("decoded value exceeds 2^53 on its grid")
        out[:, c] = from_grid(values, f).astype(np.float32)
    return out


def check_finite(values: np.ndarray, chunk: str) -> None:
    """FormatError when a decoded stream holds a non-finite value (float32 overflow)."""
    if values.size and not np.all(np.isfinite(values)):
        raise FormatError("decoded values overflow float32", chunk=chunk)
