"""Residual coding: integer values against integer means, steps and frozen Gaussian tables.

Arithmetic (spec/FORMAT.md §16.3), all in exact int64:

    q = step_size(step_idx)                      # integer step on the value grid
    r = floor((2 * (a - mu) + q) / (2 * q))      # round half up of (a - mu) / q
    reconstruction = mu + q * r

Each residual is coded with the Gaussian table of its scale index; residuals outside the
table's [-K, K] code the escape symbol and go, as varints, into a side stream. Symbols are
coded grouped by table, tables in increasing index and values in increasing position within
a table, one constriction call per table.
"""

from __future__ import annotations

import constriction
import numpy as np

from csgs_codec.entropy.grouping import groups_by_key
from csgs_codec.entropy.tables import gaussian_family, table_model
from csgs_codec.entropy.varints import decode_varints, encode_varints
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Largest |value| and |mean| on the value grid (so every intermediate fits int64 exactly).
VALUE_LIMIT = 1 << 53
#: Largest |residual| :func:`encode_symbols` accepts.
RESIDUAL_LIMIT = 1 << 62
#: Number of step indices: q_j = g(j + 1), g(m) = m below 16, (8 + m mod 8) 2^(m // 8 - 1) above.
STEP_COUNT = 176
#: Most values one stream may hold (a decoder limit; 2^32 - 1).
MAX_COUNT = (1 << 32) - 1
#: Where a payload's value count is not fixed by data decoded before it (network weights,
#: MLP weights), it may be at most this many values per payload byte left, plus
#: CODED_VALUE_SLACK: a decoder's allocation then stays bounded by the bytes it was given.
CODED_VALUES_PER_BYTE = 4
CODED_VALUE_SLACK = 1 << 16


def coded_value_limit(bytes_left: int) -> int:
    """Most values an array coded in the rest of a payload may hold (see
    :data:`CODED_VALUES_PER_BYTE`); encoders whose arrays exceed it use a fixed-width form."""
    return CODED_VALUES_PER_BYTE * bytes_left + CODED_VALUE_SLACK


def step_size(step_idx: np.ndarray) -> np.ndarray:
    """Integer step q for each step index: (N,) int in [0, 176) -> (N,) int64 in [1, 2^24].

    q_j = g(j + 1) with g(m) = m for m < 16 and g(m) = (8 + (m mod 8)) * 2^(floor(m / 8) - 1)
    for m >= 16: the integers 1..16, then a grid of 1/8 octave (18, 20, ..., 30, 32, 36, ...).
    """
    m = np.asarray(step_idx, dtype=np.int64) + 1
    big = (8 + (m & 7)) << np.maximum((m >> 3) - 1, 0)
    return np.where(m < 16, m, big)


def step_index(step: np.ndarray) -> np.ndarray:
    """Encoder helper: the step index whose q is nearest (in log scale) to each float step.

    Args:
        step: (N,) float steps in grid units (clipped to [1, 2^24]).

    Returns:
        (N,) int64 in [0, 176).
    """
    q = np.log(np.clip(np.asarray(step, dtype=np.float64), 1.0, float(1 << 24)))
    grid = np.log(step_size(np.arange(STEP_COUNT)).astype(np.float64))
    right = np.clip(np.searchsorted(grid, q), 1, STEP_COUNT - 1)
    nearer_left = (q - grid[right - 1]) <= (grid[right] - q)
    return np.where(nearer_left, right - 1, right).astype(np.int64)


def _check_index(name: str, idx: np.ndarray, count: int, n: int, err: type) -> np.ndarray:
    idx = np.asarray(idx)
    if idx.shape != (n,):
        raise err(f"{name} has shape {idx.shape}, expected ({n},)", property=name)
    if idx.size and not np.issubdtype(idx.dtype, np.integer):
        raise err(f"{name} must hold integers, got {idx.dtype}", property=name)
    idx = idx.astype(np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= count):
        bad = int(np.flatnonzero((idx < 0) | (idx >= count))[0])
        raise err(f"{name} {int(idx[bad])} is outside [0, {count})", property=name, index=bad)
    return idx


def _check_values(name: str, values: np.ndarray, limit: int) -> np.ndarray:
    values = np.asarray(values)
    if values.ndim != 1:
        raise InputError(f"{name} must be one-dimensional, got shape {values.shape}",
                         property=name)
    if values.size and not np.issubdtype(values.dtype, np.integer):
        raise InputError(f"{name} must hold integers on the value grid, got {values.dtype}; "
                         "use to_grid() for floats", property=name)
    if values.dtype == np.uint64 and values.size and values.max() > limit:
        raise InputError(f"{name} exceeds {limit}", property=name)
    values = values.astype(np.int64)
    if values.size and (values.min() < -limit or values.max() > limit):
        bad = int(np.flatnonzero(np.abs(values.clip(-limit - 1, limit + 1)) > limit)[0])
        raise InputError(f"{name} {int(values[bad])} is outside [-2^{limit.bit_length() - 1}, "
                         f"2^{limit.bit_length() - 1}]", property=name, index=bad)
    return values


def to_grid(values: np.ndarray, frac_bits: int) -> np.ndarray:
    """Floats to the integer value grid: (N,) float -> (N,) int64 round(values * 2^frac_bits).

    Encoder side only (its result is what gets coded). Raises InputError on NaN/inf or values
    outside the grid's range.
    """
    values = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(values)):
        raise InputError("values must be finite to be placed on the grid")
    scaled = np.rint(np.ldexp(values, frac_bits))
    if scaled.size and np.abs(scaled).max() > VALUE_LIMIT:
        raise InputError(f"values exceed 2^53 grid units at frac_bits={frac_bits}")
    return scaled.astype(np.int64)


def from_grid(values: np.ndarray, frac_bits: int) -> np.ndarray:
    """Grid integers to floats: (N,) int64 -> (N,) float64 values * 2^-frac_bits (exact)."""
    return np.ldexp(np.asarray(values, dtype=np.int64).astype(np.float64), -frac_bits)


def quantize(values: np.ndarray, mean: np.ndarray, step_idx: np.ndarray) -> np.ndarray:
    """Residual indices r = floor((2(a - mu) + q) / 2q): three (N,) int arrays -> (N,) int64."""
    a = _check_values("values", values, VALUE_LIMIT)
    mu = _check_values("mean", mean, VALUE_LIMIT)
    if mu.shape != a.shape:
        raise InputError(f"mean has shape {mu.shape}, values {a.shape}", property="mean")
    q = step_size(_check_index("step_idx", step_idx, STEP_COUNT, a.size, InputError))
    return (2 * (a - mu) + q) // (2 * q)


def reconstruct(mean: np.ndarray, residuals: np.ndarray, step_idx: np.ndarray) -> np.ndarray:
    """What the decoder outputs: mu + q * r, (N,) int64 (exact integer arithmetic)."""
    mu = np.asarray(mean, dtype=np.int64)
    return mu + step_size(step_idx) * np.asarray(residuals, dtype=np.int64)


def reconstructed_values(values: np.ndarray, mean: np.ndarray,
                         step_idx: np.ndarray) -> np.ndarray:
    """The decoder's output for these inputs, (N,) int64: ``reconstruct(mean, quantize(...))``.

    The encoder uses it so its own reconstruction equals the decoder's bit for bit.
    """
    return reconstruct(mean, quantize(values, mean, step_idx), step_idx)


def encode_symbols(residuals: np.ndarray, scale_idx: np.ndarray) -> bytes:
    """Code integer residuals with the frozen Gaussian tables; any |r| <= 2^62 round-trips.

    Args:
        residuals: (N,) integers.
        scale_idx: (N,) integers in [0, 64), the table of each residual.

    Returns:
        The residual stream (spec/FORMAT.md §16.3.3).
    """
    r = _check_values("residuals", residuals, RESIDUAL_LIMIT)
    n = r.size
    if n > MAX_COUNT:
        raise InputError(f"{n} residuals exceed the stream limit {MAX_COUNT}")
    family = gaussian_family()
    scale = _check_index("scale_idx", scale_idx, family.count, n, InputError)
    encoder = constriction.stream.queue.RangeEncoder()
    escapes = []
    for table, pos in groups_by_key(scale):
        half = int(family.half_widths[table])
        vals = r[pos]
        outside = np.abs(vals) > half
        symbols = np.where(outside, 2 * half + 1, vals + half).astype(np.int32)
        encoder.encode(symbols, table_model(table))
        if outside.any():
            esc = vals[outside]
            # 2 * (|r| - K - 1) + sign: |r| - K - 1 >= 0 for every escaped residual.
            escapes.append(((np.abs(esc) - half - 1).astype(np.uint64) << np.uint64(1))
                           | (esc < 0).astype(np.uint64))
    words = encoder.get_compressed()
    out = ByteWriter()
    out.varint(n)
    out.varint(int(words.size))
    out.array(words, "<u4")
    if escapes:
        out.raw(encode_varints(np.concatenate(escapes)))
    return out.getvalue()


def decode_symbols(data: bytes, scale_idx: np.ndarray, *, chunk: str | None = None,
                   base_offset: int = 0) -> np.ndarray:
    """Decode what :func:`encode_symbols` wrote: (N,) table indices -> (N,) int64 residuals.

    Raises FormatError (naming ``chunk`` and the absolute byte offset) when the stream is
    malformed, truncated, has trailing bytes or holds a different count than ``scale_idx``.
    """
    family = gaussian_family()
    reader = ByteReader(data, base_offset=base_offset, chunk=chunk)
    n = reader.varint("count", maximum=MAX_COUNT)
    scale = np.asarray(scale_idx)
    if scale.shape != (n,):
        raise reader.error(f"stream holds {n} residuals, the caller expects {scale.shape}")
    scale = _check_index("scale_idx", scale, family.count, n, FormatError)
    n_words = reader.varint("word_count", maximum=reader.remaining // 4)
    words = reader.array(n_words, "<u4", "range_data").astype(np.uint32)
    decoder = constriction.stream.queue.RangeDecoder(words)
    residuals = np.empty(n, dtype=np.int64)
    escaped_pos, escaped_half = [], []
    for table, pos in groups_by_key(scale):
        half = int(family.half_widths[table])
        try:
            symbols = decoder.decode(table_model(table), pos.size).astype(np.int64)
        except (AssertionError, ValueError, RuntimeError, OverflowError) as exc:
            raise reader.error(f"range decoder failed in table {table} ({exc})") from exc
        residuals[pos] = symbols - half
        outside = symbols == 2 * half + 1
        if outside.any():
            escaped_pos.append(pos[outside])
            escaped_half.append(np.full(int(outside.sum()), half, dtype=np.int64))
    if escaped_pos:
        where = np.concatenate(escaped_pos)
        half = np.concatenate(escaped_half)
        start = reader.offset
        codes = decode_varints(reader.raw(reader.remaining, "escapes"), where.size,
                               chunk=chunk, base_offset=start)
        excess = codes >> np.uint64(1)
        magnitude = np.minimum(excess, np.uint64(RESIDUAL_LIMIT)).astype(np.int64) + half + 1
        if magnitude.max() > RESIDUAL_LIMIT:
            raise FormatError("escaped residual exceeds 2^62", chunk=chunk, offset=start)
        residuals[where] = np.where(codes & np.uint64(1), -magnitude, magnitude)
    reader.expect_end("the residual stream")
    return residuals


def encode_residuals(values: np.ndarray, mean: np.ndarray, scale_idx: np.ndarray,
                     step_idx: np.ndarray) -> bytes:
    """Quantize and code one attribute channel: a = values, mu = mean on the integer grid.

    Args:
        values: (N,) int, the values on the grid (see :func:`to_grid`), |a| <= 2^53.
        mean: (N,) int, predicted means on the same grid, |mu| <= 2^53.
        scale_idx: (N,) int in [0, 64), Gaussian table of sigma / q.
        step_idx: (N,) int in [0, 176), step q = step_size(step_idx) in grid units.

    Returns:
        The residual stream; the decoder returns ``reconstructed_values(values, mean,
        step_idx)``.
    """
    return encode_symbols(quantize(values, mean, step_idx), scale_idx)


def decode_residuals(data: bytes, mean: np.ndarray, scale_idx: np.ndarray,
                     step_idx: np.ndarray, *, chunk: str | None = None,
                     base_offset: int = 0) -> np.ndarray:
    """Decode :func:`encode_residuals`' stream: (N,) mean, scale, step -> (N,) int64 values."""
    mu = np.asarray(mean)
    if mu.ndim != 1 or (mu.size and not np.issubdtype(mu.dtype, np.integer)):
        raise FormatError("mean must be a one-dimensional integer array", chunk=chunk)
    mu = mu.astype(np.int64)
    if mu.size and np.abs(mu).max() > VALUE_LIMIT:
        raise FormatError("mean exceeds 2^53", chunk=chunk)
    step = _check_index("step_idx", step_idx, STEP_COUNT, mu.size, FormatError)
    residuals = decode_symbols(data, scale_idx, chunk=chunk, base_offset=base_offset)
    if residuals.size != mu.size:
        raise FormatError(f"stream holds {residuals.size} values, mean has {mu.size}",
                          chunk=chunk)
    q = step_size(step)
    # |mu + q r| must stay on the int64 grid: |r| <= (2^62 - |mu|) / q.
    if residuals.size and np.any(np.abs(residuals) > (RESIDUAL_LIMIT - np.abs(mu)) // q):
        raise FormatError("decoded value leaves the 2^62 grid range", chunk=chunk)
    return mu + q * residuals
