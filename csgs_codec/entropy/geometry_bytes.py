"""Byte-level pieces of the geometry payload: LEB128 varints and fixed-width raw bit fields.

Varints are unsigned LEB128 (7 bits per byte, least significant group first, high bit set on
every byte but the last), at most ten bytes and below ``2^64`` (FORMAT §2.2). Raw bit fields
are written most significant bit first into bytes filled from their most significant bit.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.entropy.varints import encode_varints
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, encode_varint

#: Longest varint accepted (FORMAT §2.2: ten bytes, values below 2^64).
MAX_VARINT_BYTES = 10


def write_varint(value: int) -> bytes:
    """Unsigned LEB128 bytes of ``0 <= value < 2^64`` (FORMAT §2.2)."""
    return encode_varint(value)


def read_varint(data: bytes, offset: int, what: str) -> tuple[int, int]:
    """Read one varint at ``offset``; returns (value, offset after it).

    Raises:
        FormatError: truncated, over ten bytes, above 2^64 - 1 or not in shortest form.
    """
    reader = ByteReader(memoryview(data)[offset:], base_offset=offset)
    try:
        value = reader.varint(what)
    except FormatError as err:
        raise FormatError(f"geometry: {err.message}", offset=err.offset) from None
    return value, reader.offset


def write_varints(values: np.ndarray) -> bytes:
    """Concatenated varints of (K,) non-negative integers below ``2^64`` (vectorised)."""
    return encode_varints(values)


def read_varints(data: bytes, offset: int, count: int, what: str) -> tuple[np.ndarray, int]:
    """Read ``count`` consecutive varints (vectorised); returns ((count,) uint64, new offset).

    Raises:
        FormatError: truncated, a varint over ten bytes or above 2^64 - 1, or one not in its
            shortest form.
    """
    if count == 0:
        return np.zeros(0, np.uint64), offset
    window = np.frombuffer(data, np.uint8, count=min(len(data) - offset,
                                                     count * MAX_VARINT_BYTES), offset=offset)
    ends = np.flatnonzero(window < 0x80)
    if ends.size < count:
        raise FormatError(f"geometry: truncated varint list ({what})", offset=offset)
    ends = ends[:count]
    lengths = np.diff(np.concatenate(([-1], ends)))
    if lengths.max() > MAX_VARINT_BYTES:
        raise FormatError(f"geometry: varint longer than 10 bytes ({what})", offset=offset)
    if np.any((lengths == MAX_VARINT_BYTES) & (window[ends] > 1)):
        raise FormatError(f"geometry: varint above 2^64 - 1 ({what})", offset=offset)
    if np.any((lengths > 1) & (window[ends] == 0)):
        raise FormatError(f"geometry: varint not in shortest form ({what})", offset=offset)
    used = window[: ends[-1] + 1]
    owner = np.repeat(np.arange(count), lengths)
    position = np.arange(used.size) - (ends - lengths + 1)[owner]
    parts = (used & 0x7F).astype(np.uint64) << (7 * position).astype(np.uint64)
    values = np.zeros(count, np.uint64)
    np.bitwise_or.at(values, owner, parts)
    return values, offset + used.size


def field_bits(values: np.ndarray, width: int) -> np.ndarray:
    """(K,) uint64 values of ``width <= 63`` bits -> (K * width,) uint8 bits, MSB first."""
    shifts = np.arange(width - 1, -1, -1, dtype=np.uint64)
    return ((values[:, None] >> shifts) & np.uint64(1)).astype(np.uint8).ravel()


def read_fields(raw: np.ndarray, bit_offset: int, count: int, width: int) -> np.ndarray:
    """Read ``count`` fields of ``width <= 63`` bits starting at ``bit_offset`` of ``raw``.

    Args:
        raw: (B,) uint8 bytes of the raw section; the caller checks that the fields fit.

    Returns:
        (count,) uint64 values.
    """
    starts = bit_offset + width * np.arange(count, dtype=np.int64)
    padded = np.concatenate((raw, np.zeros(8, np.uint8)))
    if width <= 57:
        return _read_window(padded, starts, width)
    high = _read_window(padded, starts, width - 32)
    low = _read_window(padded, starts + (width - 32), 32)
    return (high << np.uint64(32)) | low


def _read_window(padded: np.ndarray, starts: np.ndarray, width: int) -> np.ndarray:
    """Fields of ``width <= 57`` bits at bit positions ``starts`` (MSB first) -> uint64."""
    first = starts >> 3
    window = padded[first[:, None] + np.arange(8)].view(">u8").ravel().astype(np.uint64)
    # Drop the bits before the field (overflow discards them), then keep the top ``width``.
    return (window << (starts & 7).astype(np.uint64)) >> np.uint64(64 - width)
