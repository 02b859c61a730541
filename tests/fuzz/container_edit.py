"""Take .csgs bytes apart into chunks, put them back together with arbitrary (lying) fields,
and recompute CRCs after a byte-level mutation.

The format reader checks the TOC CRC and every chunk CRC before a chunk decoder sees a byte,
so a mutant whose CRCs are stale never reaches the chunk decoders. :func:`repair_crcs`
recomputes every CRC that the (possibly damaged) header and TOC still locate, so the fuzzer
exercises the payload parsers and not only the CRC check.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from csgs_codec.errors import FormatError
from csgs_codec.format import ByteReader, crc32, read_layers
from csgs_codec.format.layout import FRAME_OVERHEAD, HEADER_SIZE, MAGIC, TOC_CRC_SIZE
from csgs_codec.format.writer import encode_toc_body

_HEADER = struct.Struct("<8sBBHI")
_U32 = struct.Struct("<I")


@dataclass
class RawChunk:
    """One chunk as bytes, with no validation: 4-byte type, layer number, tile, payload."""

    type: bytes
    layer: int
    tile: int
    payload: bytes


@dataclass
class Frame:
    """One chunk frame as written: the length field, type bytes, payload, CRC (None: correct)."""

    length: int
    type: bytes
    payload: bytes
    crc: int | None = None

    def to_bytes(self) -> bytes:
        """length (u32) | type (4) | payload | CRC-32 of type + payload (u32)."""
        crc = crc32(self.payload, crc32(self.type)) if self.crc is None else self.crc
        return (_U32.pack(self.length & 0xFFFFFFFF) + self.type + self.payload
                + _U32.pack(crc & 0xFFFFFFFF))


@dataclass
class Layout:
    """A container before serialisation: header fields, TOC rows and frames, all editable.

    ``rows`` are [type, layer, tile, offset, length] lists; ``frames`` hold what is written.
    ``toc_size`` and ``toc_crc`` of None mean "the true value".
    """

    major: int = 1
    minor: int = 0
    flags: int = 0
    rows: list[list] = field(default_factory=list)
    frames: list[Frame] = field(default_factory=list)
    toc_size: int | None = None
    toc_crc: int | None = None

    def to_bytes(self) -> bytes:
        """Header | TOC body | TOC CRC | frames, with whatever values the fields hold."""
        body = encode_toc_body(tuple(row) for row in self.rows)
        size = len(body) if self.toc_size is None else self.toc_size
        head = _HEADER.pack(MAGIC, self.major & 0xFF, self.minor & 0xFF, self.flags & 0xFFFF,
                            size & 0xFFFFFFFF) + body
        crc = crc32(head) if self.toc_crc is None else self.toc_crc
        return head + _U32.pack(crc & 0xFFFFFFFF) + b"".join(f.to_bytes() for f in self.frames)


def split_chunks(data: bytes) -> list[RawChunk]:
    """The chunks of a valid container, in file order (every layer read)."""
    container = read_layers(data, layers="color,semantic")
    return [RawChunk(e.type.encode("ascii"), int(e.layer), e.tile,
                     bytes(container.payloads.get(e.index, b"")))
            for e in container.toc]


def layout_of(chunks: list[RawChunk]) -> Layout:
    """A truthful :class:`Layout` for ``chunks`` in the given order (offsets laid out)."""
    toc_size = 0
    while True:
        offset = HEADER_SIZE + toc_size + TOC_CRC_SIZE
        rows = []
        for chunk in chunks:
            rows.append([chunk.type, chunk.layer, chunk.tile, offset, len(chunk.payload)])
            offset += len(chunk.payload) + FRAME_OVERHEAD
        size = len(encode_toc_body(tuple(row) for row in rows))
        if size == toc_size:
            break
        toc_size = size
    frames = [Frame(len(c.payload), c.type, c.payload) for c in chunks]
    return Layout(rows=rows, frames=frames)


def build(chunks: list[RawChunk]) -> bytes:
    """Container bytes for ``chunks`` as they are (no layer, type or order checks)."""
    return layout_of(chunks).to_bytes()


def _toc_frames(data: bytes | bytearray, toc_size: int) -> list[tuple[int, int]]:
    """(offset, length) of each TOC entry that still parses; stops at the first bad one."""
    reader = ByteReader(bytes(data[HEADER_SIZE:HEADER_SIZE + toc_size]), HEADER_SIZE)
    out = []
    try:
        count = reader.varint("chunk_count")
        for _ in range(count):
            reader.raw(5, "type and layer")
            reader.varint("tile")
            offset = reader.varint("offset")
            length = reader.varint("length")
            out.append((offset, length))
    except FormatError:
        pass
    return out


def repair_crcs(data: bytes | bytearray) -> bytes:
    """``data`` with the TOC CRC and every chunk CRC the TOC locates recomputed.

    Frames are located the way the reader locates them (by TOC offset and TOC length); a frame
    that runs past the end of ``data`` is left alone.
    """
    out = bytearray(data)
    if len(out) < HEADER_SIZE:
        return bytes(out)
    toc_size = _U32.unpack_from(out, 12)[0]
    toc_end = HEADER_SIZE + toc_size
    if toc_end + TOC_CRC_SIZE > len(out):
        return bytes(out)
    _U32.pack_into(out, toc_end, crc32(bytes(out[:toc_end])))
    for offset, length in _toc_frames(out, toc_size):
        crc_at = offset + 8 + length
        if offset < toc_end + TOC_CRC_SIZE or crc_at + 4 > len(out):
            continue
        _U32.pack_into(out, crc_at, crc32(bytes(out[offset + 4:crc_at])))
    return bytes(out)
