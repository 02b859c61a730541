"""The OUTQ payload (FORMAT §12.20): far points with relative precision, both directions.

Layout: varint count Q, u8 mantissa bits b, the centre as three f64, Q exponent bytes
(e = byte - 128), then the 3 Q mantissas as unsigned (b + 1)-bit fields u = m + 2^b, packed
least significant bit first (field k = 3 i + a holds point i's axis a), the last byte's unused
high bits zero. The arithmetic is in :mod:`csgs_codec.scene.far_positions`.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.format.primitives import ByteReader, ByteWriter
from csgs_codec.scene.far_positions import MAX_MANTISSA_BITS, dequantize_far

EXPONENT_BIAS = 128


def far_payload(centre, mantissa_bits: int, exponents: np.ndarray,
                mantissas: np.ndarray) -> bytes:
    """The OUTQ payload of Q points: ``centre`` (3,) float64, ``exponents`` (Q,) int in
    [-128, 127], ``mantissas`` (Q, 3) int in [-2^b, 2^b - 1]."""
    out = ByteWriter()
    e = np.asarray(exponents, np.int64).reshape(-1)
    out.varint(len(e))
    out.fixed("u8", mantissa_bits)
    for v in centre:
        out.fixed("f64", float(v))
    out.raw((e + EXPONENT_BIAS).astype(np.uint8).tobytes())
    out.raw(_pack(np.asarray(mantissas, np.int64).reshape(-1) + (1 << mantissa_bits),
                  mantissa_bits + 1))
    return out.getvalue()


def read_far_payload(data, base_offset: int, max_count: int) -> np.ndarray:
    """The decoded far positions (Q, 3) float32 of an OUTQ payload, Q <= ``max_count``.

    Raises:
        FormatError: naming OUTQ and the byte offset, when a field is out of range, the
            payload is truncated or too long, a padding bit is set or a decoded position
            is not a finite float32.
    """
    r = ByteReader(data, base_offset=base_offset, chunk="OUTQ")
    start = r.offset
    count = r.varint("count", maximum=max_count)
    if count == 0:
        raise r.error("an OUTQ chunk must hold at least one point", at=start)
    at = r.offset
    bits = r.fixed("u8", "mantissa_bits")
    if not 1 <= bits <= MAX_MANTISSA_BITS:
        raise r.error(f"mantissa_bits {bits} outside 1..{MAX_MANTISSA_BITS}", at=at)
    at = r.offset
    centre = tuple(r.fixed("f64", f"centre_{a}") for a in "xyz")
    if not all(np.isfinite(centre)):
        raise r.error("the centre must be finite", at=at)
    exponents = r.array(count, "u1", "exponents").astype(np.int64) - EXPONENT_BIAS
    width = bits + 1
    at = r.offset
    packed = r.raw(_packed_size(3 * count, width), "mantissas")
    r.expect_end("the OUTQ payload")
    fields = _unpack(packed, 3 * count, width)
    if fields is None:
        raise r.error("padding bits after the last mantissa are not zero",
                      at=at + len(packed) - 1)
    mantissas = fields.reshape(count, 3) - (1 << bits)
    positions = dequantize_far(centre, bits, exponents, mantissas)
    if not np.all(np.isfinite(positions)):
        raise r.error("a far point decodes beyond the float32 range", at=start)
    return positions


def _packed_size(fields: int, width: int) -> int:
    return (fields * width + 7) // 8


def _pack(values: np.ndarray, width: int) -> bytes:
    """``values`` (K,) unsigned, each below 2^width, as K width-bit fields, LSB first."""
    bits = ((values[:, None] >> np.arange(width)) & 1).astype(np.uint8).reshape(-1)
    return np.packbits(bits, bitorder="little").tobytes()


def _unpack(data: bytes, fields: int, width: int) -> np.ndarray | None:
    """(fields,) int64 of what :func:`_pack` wrote, or None when a padding bit is set."""
    bits = np.unpackbits(np.frombuffer(data, np.uint8), bitorder="little")
    if bits[fields * width:].any():
        return None
    grid = bits[:fields * width].reshape(fields, width).astype(np.int64)
    return grid @ (np.int64(1) << np.arange(width, dtype=np.int64))
