"""Whole-array LEB128 varints (spec FORMAT §2.2): the escape side stream of residual coding.

Vectorised so that streams with many escapes cost no per-value Python work. Decoding checks
shortest form, the 2^64 - 1 limit, the count and the end of the data, with FormatError.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import FormatError

_MAX_BYTES = 10


def encode_varints(values: np.ndarray) -> bytes:
    """(E,) non-negative integers < 2^64 -> concatenated shortest-form LEB128 bytes."""
    v = np.asarray(values, dtype=np.uint64)
    if v.size == 0:
        return b""
    groups = np.ones(v.shape, dtype=np.int64)
    for k in range(1, _MAX_BYTES):
        groups += (v >> np.uint64(7 * k)) > 0
    k = np.arange(_MAX_BYTES, dtype=np.uint64)
    digits = ((v[:, None] >> (np.uint64(7) * k)) & np.uint64(0x7F)).astype(np.uint8)
    more = np.arange(_MAX_BYTES)[None, :] < (groups[:, None] - 1)
    digits |= np.where(more, 0x80, 0).astype(np.uint8)
    keep = np.arange(_MAX_BYTES)[None, :] < groups[:, None]
    return digits[keep].tobytes()


def decode_varints(data: bytes, count: int, *, chunk: str | None = None,
                   base_offset: int = 0) -> np.ndarray:
    """Exactly ``count`` varints filling ``data`` -> (count,) uint64; FormatError otherwise."""
    raw = np.frombuffer(data, dtype=np.uint8)
    ends = np.flatnonzero(raw < 0x80)
    if ends.size != count or (count and ends[-1] != raw.size - 1) or (not count and raw.size):
        raise FormatError(f"escape stream holds {ends.size} complete varints in {raw.size} "
                          f"bytes, expected exactly {count}", chunk=chunk, offset=base_offset)
    if count == 0:
        return np.zeros(0, dtype=np.uint64)
    starts = np.concatenate(([0], ends[:-1] + 1))
    lengths = ends - starts + 1
    if lengths.max() > _MAX_BYTES:
        bad = int(np.argmax(lengths > _MAX_BYTES))
        raise FormatError("escape varint longer than 10 bytes", chunk=chunk,
                          offset=base_offset + int(starts[bad]))
    noncanonical = (lengths > 1) & (raw[ends] == 0)
    overflow = (lengths == _MAX_BYTES) & (raw[ends] > 1)
    if noncanonical.any() or overflow.any():
        bad = int(np.argmax(noncanonical | overflow))
        raise FormatError("escape varint is not in shortest form or exceeds 2^64 - 1",
                          chunk=chunk, offset=base_offset + int(starts[bad]))
    owner = np.repeat(np.arange(count), lengths)
    shift = (np.arange(raw.size) - starts[owner]).astype(np.uint64) * np.uint64(7)
    parts = (raw & 0x7F).astype(np.uint64) << shift
    # The 7-bit groups of one varint occupy disjoint bits, so their sum is their OR.
    return np.add.reduceat(parts, starts).astype(np.uint64)
