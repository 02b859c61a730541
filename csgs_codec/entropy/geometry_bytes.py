"""Byte-level pieces of the geometry payload: LEB128 varints and fixed-width raw bit fields.

Varints are unsigned LEB128 (7 bits per byte, least significant group first, high bit set on
every byte but the last), at most 9 bytes and below ``2^63``. Raw bit fields are written most
significant bit first into bytes filled from their most significant bit.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import FormatError

#: Longest varint accepted (9 bytes hold 63 bits).
MAX_VARINT_BYTES = 9


def write_varint(value: int) -> bytes:
    """Unsigned LEB128 bytes of ``0 <= value < 2^63``."""
    if not 0 <= value < 1 << 63:
        raise ValueError(f"varint out of range: {value}")
    out = bytearray()
    while True:
        low = value & 0x7F
        value >>= 7
        if value:
            out.append(low | 0x80)
        else:
            out.append(low)
            return bytes(out)


def read_varint(data: bytes, offset: int, what: str) -> tuple[int, int]:
    """Read one varint at ``offset``; returns (value, offset after it).

    Raises:
        FormatError: truncated, longer than 9 bytes, or not in its shortest form.
    """
    value = 0
    for i in range(MAX_VARINT_BYTES):
        if offset + i >= len(data):
            raise FormatError(f"geometry: truncated varint ({what})", offset=offset)
        byte = data[offset + i]
        value |= (byte & 0x7F) << (7 * i)
        if not byte & 0x80:
            if byte == 0 and i > 0:
                raise FormatError(f"geometry: varint not in shortest form ({what})", offset=offset)
            return value, offset + i + 1
    raise FormatError(f"geometry: varint longer than 9 bytes ({what})", offset=offset)


def write_varints(values: np.ndarray) -> bytes:
    """Concatenated varints of (K,) non-negative integers below ``2^63`` (vectorised)."""
    v = np.asarray(values, dtype=np.uint64)
    if v.size == 0:
        return b""
    groups = np.ones(v.size, np.int64)
    for i in range(1, MAX_VARINT_BYTES):
        groups += (v >> np.uint64(7 * i)) > 0
    owner = np.repeat(np.arange(v.size), groups)
    first = np.cumsum(groups) - groups
    position = np.arange(owner.size) - first[owner]
    out = ((v[owner] >> (7 * position).astype(np.uint64)) & np.uint64(0x7F)).astype(np.uint8)
    out[position < groups[owner] - 1] |= 0x80
    return out.tobytes()


def read_varints(data: bytes, offset: int, count: int, what: str) -> tuple[np.ndarray, int]:
    """Read ``count`` consecutive varints (vectorised); returns ((count,) uint64, new offset).

    Raises:
        FormatError: truncated, a varint over 9 bytes, or one not in its shortest form.
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
        raise FormatError(f"geometry: varint longer than 9 bytes ({what})", offset=offset)
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
