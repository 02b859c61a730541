"""Far points (FORMAT §12.4, §12.20), both directions: OUTQ, far points with relative
precision, then OUTL, the rest as exact float32. Which points go where is the encoder's
decision (:mod:`csgs_codec.decisions.far_points`).

OUTL: varint count, then (x, y, z) float32 per point.

OUTQ: varint count Q, u8 mantissa bits b, the centre as three f64, Q exponent bytes
(e = byte - 128), then the 3 Q mantissas as unsigned (b + 1)-bit fields u = m + 2^b, packed
least significant bit first (field k = 3 i + a holds point i's axis a), the last byte's unused
high bits zero. The arithmetic is in :mod:`csgs_codec.attributes.far_positions`.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.attributes.far_positions import MAX_MANTISSA_BITS, dequantize_far
from csgs_codec.chunks.checks import check_finite
from csgs_codec.format.primitives import ByteReader, ByteWriter

EXPONENT_BIAS = 128


def exact_far_payload(positions: np.ndarray) -> bytes:
    """The OUTL payload of ``positions`` (F, 3), stored as float32."""
    out = ByteWriter()
    out.varint(len(positions))
    out.array(positions.astype(np.float32), "<f4")
    return out.getvalue()


def read_far_positions(container, far_count: int) -> np.ndarray:
    """(far_count, 3) float32 positions of a container's far points: those of OUTQ (when
    present) then those of OUTL; with ``far_count`` 0 (the scene header's), neither chunk
    may be there.

    Raises:
        FormatError: naming the chunk and byte offset, when a chunk is missing, present
            where it must not be, or holds another count or a non-finite position.
    """
    if not far_count:
        for code in ("OUTQ", "OUTL"):
            container.refuse_chunk(code, "the header declares no far points")
        return np.zeros((0, 3), np.float32)
    parts = []
    if any(e.type == "OUTQ" for e in container.toc):
        data, offset = container.single_payload("OUTQ")
        parts.append(read_relative_far_payload(data, offset, far_count))
    exact = far_count - sum(len(p) for p in parts)
    if not exact:
        container.refuse_chunk("OUTL", "OUTQ holds every far point")
        return np.concatenate(parts)
    data, offset = container.single_payload("OUTL")
    r = ByteReader(data, base_offset=offset, chunk="OUTL")
    n = r.varint("far_count", maximum=exact)
    if n != exact:
        raise r.error(f"{n} outliers, the header and OUTQ leave {exact}")
    far = r.array(n * 3, "<f4", "positions").reshape(n, 3).astype(np.float32)
    r.expect_end("the outlier list")
    check_finite(far, "OUTL")
    return np.concatenate(parts + [far])


def relative_far_count(container) -> int:
    """The point count of the OUTQ chunks read in all tiles (0 without one), from their
    count fields only (what ``csgs info`` reports)."""
    total = 0
    for entry in container.toc:
        if entry.type == "OUTQ" and entry.index in container.payloads:
            reader = ByteReader(bytes(container.payloads[entry.index]), entry.offset + 8,
                                chunk="OUTQ")
            total += reader.varint("count")
    return total


def relative_far_payload(centre, mantissa_bits: int, exponents: np.ndarray,
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


def read_relative_far_payload(data, base_offset: int, max_count: int) -> np.ndarray:
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
