"""Byte-level primitives of the .csgs format: LEB128 varints, zigzag, fixed ints, CRC-32.

Everything here is pure standard library (numpy, loaded on first use, for whole arrays) and
bounds-checked: a :class:`ByteReader` never returns fewer bytes than asked and never allocates
more than the bytes it already holds, and every failure is a
:class:`~csgs_codec.errors.FormatError` naming the chunk (when known) and the absolute byte
offset. spec/FORMAT.md §2 defines the encodings.
"""

from __future__ import annotations

import struct
import zlib
from typing import TYPE_CHECKING

from csgs_codec.errors import FormatError

if TYPE_CHECKING:
    import numpy as np

#: Longest LEB128 encoding of a value below 2**64 (spec/FORMAT.md §2.2).
MAX_VARINT_BYTES = 10
#: Varints hold unsigned 64-bit values.
MAX_VARINT_VALUE = (1 << 64) - 1

_FIXED = {
    "u8": struct.Struct("<B"),
    "u16": struct.Struct("<H"),
    "u32": struct.Struct("<I"),
    "u64": struct.Struct("<Q"),
    "i8": struct.Struct("<b"),
    "i16": struct.Struct("<h"),
    "i32": struct.Struct("<i"),
    "i64": struct.Struct("<q"),
    "f32": struct.Struct("<f"),
    "f64": struct.Struct("<d"),
}


def crc32(data: bytes | memoryview, crc: int = 0) -> int:
    """CRC-32 (ISO-HDLC, as in PNG and zlib) of ``data``, continuing from ``crc``.

    Polynomial 0x04C11DB7 (reflected 0xEDB88320), initial value and final XOR 0xFFFFFFFF,
    input and output reflected; ``crc32(b"123456789") == 0xCBF43926``.
    """
    return zlib.crc32(data, crc) & 0xFFFFFFFF


def encode_varint(value: int) -> bytes:
    """Unsigned LEB128 encoding of ``value`` (0 <= value < 2**64), shortest form."""
    if not isinstance(value, int) or value < 0 or value > MAX_VARINT_VALUE:
        raise FormatError(f"varint value {value!r} is outside 0..2**64-1")
    out = bytearray()
    while True:
        low = value & 0x7F
        value >>= 7
        if value:
            out.append(low | 0x80)
        else:
            out.append(low)
            return bytes(out)


def zigzag_encode(value: int) -> int:
    """Map a signed 64-bit integer to unsigned: 0, -1, 1, -2, ... -> 0, 1, 2, 3, ..."""
    if not isinstance(value, int) or not -(1 << 63) <= value < (1 << 63):
        raise FormatError(f"zigzag value {value!r} is outside the signed 64-bit range")
    return (value << 1) if value >= 0 else ((-value) << 1) - 1


def zigzag_decode(value: int) -> int:
    """Inverse of :func:`zigzag_encode` for 0 <= value < 2**64."""
    return (value >> 1) if not value & 1 else -((value + 1) >> 1)


class ByteWriter:
    """Appends format primitives to a growing byte buffer (the encoder side of ByteReader)."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def __len__(self) -> int:
        return len(self._buf)

    def getvalue(self) -> bytes:
        """The bytes written so far."""
        return bytes(self._buf)

    def raw(self, data: bytes | bytearray | memoryview) -> None:
        """Append ``data`` unchanged."""
        self._buf += data

    def fixed(self, kind: str, value: int | float) -> None:
        """Append one little-endian fixed-size number; ``kind`` is u8..u64, i8..i64, f32, f64."""
        try:
            self._buf += _FIXED[kind].pack(value)
        except (KeyError, struct.error) as exc:
            raise FormatError(f"cannot write {value!r} as {kind}: {exc}") from None

    def varint(self, value: int) -> None:
        """Append an unsigned LEB128 varint."""
        self._buf += encode_varint(value)

    def svarint(self, value: int) -> None:
        """Append a signed integer as the varint of its zigzag mapping."""
        self._buf += encode_varint(zigzag_encode(value))

    def byte_string(self, data: bytes) -> None:
        """Append a length-prefixed byte string: varint length, then the bytes."""
        self.varint(len(data))
        self._buf += data

    def array(self, values: np.ndarray, dtype: str) -> None:
        """Append a numpy array as little-endian ``dtype`` values in C order (no length)."""
        import numpy as np  # imported here so that header/TOC reading never loads numpy

        self._buf += np.ascontiguousarray(values, dtype=np.dtype(dtype).newbyteorder("<")).tobytes()


class ByteReader:
    """Reads format primitives from a byte buffer with every size checked before use.

    Args:
        data: the bytes to read (kept as a memoryview, not copied).
        base_offset: absolute offset of ``data[0]`` in the file, used in error messages.
        chunk: four-character chunk type named in errors, if the bytes are a chunk payload.
    """

    def __init__(self, data: bytes | memoryview, base_offset: int = 0,
                 chunk: str | None = None) -> None:
        self._view = memoryview(data).cast("B")
        self._pos = 0
        self.base_offset = base_offset
        self.chunk = chunk

    @property
    def position(self) -> int:
        """Bytes consumed so far (relative to the start of ``data``)."""
        return self._pos

    @property
    def offset(self) -> int:
        """Absolute file offset of the next byte."""
        return self.base_offset + self._pos

    @property
    def remaining(self) -> int:
        """Bytes not yet consumed."""
        return len(self._view) - self._pos

    def error(self, message: str, at: int | None = None) -> FormatError:
        """A FormatError for this buffer at absolute offset ``at`` (default: the next byte)."""
        return FormatError(message, chunk=self.chunk, offset=self.offset if at is None else at)

    def _take(self, n: int, field: str) -> memoryview:
        if n < 0 or n > self.remaining:
            raise self.error(f"truncated: field '{field}' needs {n} bytes, "
                             f"{self.remaining} remain", at=self.base_offset + len(self._view))
        out = self._view[self._pos:self._pos + n]
        self._pos += n
        return out

    def raw(self, n: int, field: str) -> bytes:
        """The next ``n`` bytes (checked against what remains before copying)."""
        return bytes(self._take(n, field))

    def fixed(self, kind: str, field: str) -> int | float:
        """One little-endian fixed-size number; ``kind`` is u8..u64, i8..i64, f32, f64."""
        codec = _FIXED[kind]
        return codec.unpack(self._take(codec.size, field))[0]

    def varint(self, field: str, maximum: int = MAX_VARINT_VALUE) -> int:
        """An unsigned LEB128 varint in canonical (shortest) form, checked against ``maximum``."""
        pos = self._pos
        if pos < len(self._view) and self._view[pos] < 0x80:  # fast path: one byte
            value = self._view[pos]
            if value <= maximum:
                self._pos = pos + 1
                return value
        start = self.offset
        value = 0
        for i in range(MAX_VARINT_BYTES):
            if self.remaining == 0:
                raise self.error(f"truncated: varint field '{field}' runs past the end")
            byte = self._view[self._pos]
            self._pos += 1
            value |= (byte & 0x7F) << (7 * i)
            if not byte & 0x80:
                if i > 0 and byte == 0:
                    raise self.error(f"varint field '{field}' is not in shortest form", at=start)
                if value > MAX_VARINT_VALUE:
                    raise self.error(f"varint field '{field}' exceeds 2**64-1", at=start)
                if value > maximum:
                    raise self.error(f"field '{field}' = {value} exceeds the limit {maximum}",
                                     at=start)
                return value
        raise self.error(f"varint field '{field}' is longer than {MAX_VARINT_BYTES} bytes",
                         at=start)

    def svarint(self, field: str) -> int:
        """A signed integer stored as the varint of its zigzag mapping."""
        return zigzag_decode(self.varint(field))

    def byte_string(self, field: str, maximum: int | None = None) -> bytes:
        """A length-prefixed byte string; the length is checked before anything is copied."""
        limit = self.remaining if maximum is None else min(maximum, self.remaining)
        start = self.offset
        length = self.varint(field)
        if length > limit:
            raise self.error(f"field '{field}' declares {length} bytes, only {limit} allowed",
                             at=start)
        return self.raw(length, field)

    def array(self, count: int, dtype: str, field: str) -> np.ndarray:
        """``count`` little-endian ``dtype`` values as a read-only (count,) numpy array."""
        import numpy as np  # imported here so that header/TOC reading never loads numpy

        item = np.dtype(dtype).newbyteorder("<")
        if count < 0 or count > self.remaining // max(item.itemsize, 1):
            raise self.error(f"truncated: field '{field}' needs {count} x {item.itemsize} "
                             f"bytes, {self.remaining} remain",
                             at=self.base_offset + len(self._view))
        return np.frombuffer(self._take(count * item.itemsize, field), dtype=item, count=count)

    def expect_end(self, what: str) -> None:
        """Raise unless every byte has been consumed (trailing bytes are invalid)."""
        if self.remaining:
            raise self.error(f"{self.remaining} unexpected bytes after the last field of {what}")
