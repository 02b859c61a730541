"""Histogram-coded integer symbols: a static frequency table made from the data and sent along.

Where a channel's residuals are not Gaussian (bimodal opacities, skewed colors), the frozen
Gaussian tables waste bits; a table of the residuals' own frequencies (the empirical, per-
channel "factorized" density) codes them within a few hundredths of a bit of their
zeroth-order entropy, for a table of a few dozen bytes.

Stream (FORMAT §16.5): varint N, svarint lo, varint K (1..4096), K + 1 varint frequencies
(symbol lo + s for s < K, then the escape symbol), each >= 1 and together 2^16; varint word
count W, W little-endian u32 range-coder words; then one zigzag varint per escaped value
(values outside [lo, lo + K)), in stream order.
"""

from __future__ import annotations

import constriction
import numpy as np

from csgs_codec.entropy.coder_model import TOTAL, categorical_model
from csgs_codec.entropy.geometry_models import normalized_frequencies
from csgs_codec.entropy.varints import decode_varints, encode_varints
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter

MAX_SYMBOLS = 4096
MAX_COUNT = (1 << 32) - 1
VALUE_LIMIT = 1 << 62
#: Share of values left to escapes at each end when the range would exceed MAX_SYMBOLS.
TAIL_SHARE = 1e-4


def _range(values: np.ndarray) -> tuple[int, int]:
    """(lo, K) of the coded symbol range for ``values`` (N,) int64, N > 0."""
    lo, hi = int(values.min()), int(values.max())
    if hi - lo + 1 > MAX_SYMBOLS:
        lo, hi = (int(v) for v in np.quantile(values, [TAIL_SHARE, 1 - TAIL_SHARE],
                                               method="nearest"))
        if hi - lo + 1 > MAX_SYMBOLS:
            centre = int(np.median(values))
            lo, hi = centre - MAX_SYMBOLS // 2, centre + MAX_SYMBOLS // 2 - 1
    return lo, hi - lo + 1


def _symbols(values: np.ndarray, lo: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    inside = (values >= lo) & (values < lo + k)
    return np.where(inside, values - lo, k).astype(np.int32), ~inside


def _zigzag(values: np.ndarray) -> np.ndarray:
    v = values.astype(np.int64)
    return ((v << 1) ^ (v >> 63)).astype(np.uint64)


def _unzigzag(codes: np.ndarray) -> np.ndarray:
    c = codes.astype(np.uint64)
    return ((c >> np.uint64(1)).astype(np.int64)) ^ -((c & np.uint64(1)).astype(np.int64))




def _table(values: np.ndarray) -> tuple[int, int, np.ndarray]:
    lo, k = _range(values)
    symbols, _ = _symbols(values, lo, k)
    return lo, k, normalized_frequencies(np.bincount(symbols, minlength=k + 1)[None, :])[0]


def histogram_cost(values: np.ndarray) -> float:
    """Coded size in bits of ``values`` (N,) int under :func:`encode_histogram` (estimate
    accurate to the range coder's few bytes of flush)."""
    v = np.asarray(values, dtype=np.int64)
    if v.size == 0:
        return 0.0
    lo, k, freqs = _table(v)
    symbols, outside = _symbols(v, lo, k)
    bits = float(np.sum(-np.log2(freqs[symbols] / TOTAL)))
    table_bits = 8 * sum(max(1, (int(f).bit_length() + 6) // 7) for f in freqs) + 48
    escape_bits = 8 * len(encode_varints(_zigzag(v[outside]))) if outside.any() else 0
    return bits + table_bits + escape_bits


def encode_histogram(values: np.ndarray) -> bytes:
    """Code (N,) integers (|v| <= 2^62) with a frequency table of their own."""
    v = np.asarray(values)
    if v.ndim != 1 or (v.size and not np.issubdtype(v.dtype, np.integer)):
        raise InputError("histogram symbols must be a one-dimensional integer array")
    v = v.astype(np.int64)
    if v.size > MAX_COUNT or (v.size and np.abs(v).max() > VALUE_LIMIT):
        raise InputError("histogram symbols exceed the stream limits")
    out = ByteWriter()
    out.varint(int(v.size))
    if v.size == 0:
        return out.getvalue()
    lo, k, freqs = _table(v)
    symbols, outside = _symbols(v, lo, k)
    out.svarint(lo)
    out.varint(k)
    for f in freqs:
        out.varint(int(f))
    encoder = constriction.stream.queue.RangeEncoder()
    encoder.encode(symbols, categorical_model(freqs))
    words = encoder.get_compressed()
    out.varint(int(words.size))
    out.array(words, "<u4")
    if outside.any():
        out.raw(encode_varints(_zigzag(v[outside])))
    return out.getvalue()


def decode_histogram(data: bytes, count: int, *, chunk: str | None = None,
                     base_offset: int = 0) -> np.ndarray:
    """Decode :func:`encode_histogram`'s stream of ``count`` values: (count,) int64.

    Raises:
        FormatError: wrong count, a bad table, truncation, a bad escape or trailing bytes,
            naming ``chunk`` and the absolute byte offset.
    """
    r = ByteReader(data, base_offset=base_offset, chunk=chunk)
    n = r.varint("count", maximum=MAX_COUNT)
    if n != count:
        raise r.error(f"histogram stream holds {n} values, expected {count}")
    if n == 0:
        r.expect_end("the histogram stream")
        return np.zeros(0, np.int64)
    lo = r.svarint("lowest_symbol")
    k = r.varint("symbol_count", maximum=MAX_SYMBOLS)
    if k < 1 or abs(lo) > VALUE_LIMIT or abs(lo + k) > VALUE_LIMIT:
        raise r.error(f"symbol range [{lo}, {lo} + {k}) is invalid")
    freqs = np.array([r.varint("frequency", maximum=TOTAL) for _ in range(k + 1)], np.int64)
    if freqs.min() < 1 or int(freqs.sum()) != TOTAL:
        raise r.error("frequencies must be >= 1 and sum to 65536")
    n_words = r.varint("word_count", maximum=r.remaining // 4)
    words = r.array(n_words, "<u4", "range_data").astype(np.uint32)
    try:
        symbols = constriction.stream.queue.RangeDecoder(words).decode(categorical_model(freqs), n)
    except (AssertionError, ValueError, RuntimeError, OverflowError) as exc:
        raise r.error(f"range decoder failed ({exc})") from exc
    symbols = symbols.astype(np.int64)
    values = symbols + lo
    escaped = np.flatnonzero(symbols == k)
    if escaped.size:
        start = r.offset
        codes = decode_varints(r.raw(r.remaining, "escapes"), escaped.size, chunk=chunk,
                               base_offset=start)
        extra = _unzigzag(codes)
        if np.abs(extra).max() > VALUE_LIMIT or np.any((extra >= lo) & (extra < lo + k)):
            raise FormatError("an escaped value exceeds 2^62 or lies inside the table's range",
                              chunk=chunk,
                              offset=start)
        values[escaped] = extra
    r.expect_end("the histogram stream")
    return values
