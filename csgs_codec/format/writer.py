"""Writing .csgs containers: header, table of contents, chunk frames; atomic file output."""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable

from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import FormatError
from csgs_codec.format.chunk import Chunk
from csgs_codec.format.layout import (
    FRAME_OVERHEAD,
    HEADER_SIZE,
    KNOWN_FLAGS,
    MAGIC,
    MAJOR_VERSION,
    MAX_CHUNKS,
    MAX_TOC_SIZE,
    MINOR_VERSION,
    TOC_CRC_SIZE,
)
from csgs_codec.format.primitives import ByteWriter, crc32

_HEADER = struct.Struct("<8sBBHI")


def encode_header(toc_size: int, flags: int = 0, major: int = MAJOR_VERSION,
                  minor: int = MINOR_VERSION) -> bytes:
    """The 16-byte header: magic, major, minor, flags (u16), toc_size (u32)."""
    return _HEADER.pack(MAGIC, major, minor, flags, toc_size)


def encode_toc_body(rows: Iterable[tuple[bytes, int, int, int, int]]) -> bytes:
    """TOC body bytes from (type, layer, tile, offset, length) rows: varint count, entries."""
    rows = list(rows)
    out = ByteWriter()
    out.varint(len(rows))
    for type_code, layer, tile, offset, length in rows:
        out.raw(type_code)
        out.fixed("u8", layer)
        out.varint(tile)
        out.varint(offset)
        out.varint(length)
    return out.getvalue()


def encode_frame(type_code: bytes, payload: bytes) -> bytes:
    """One chunk frame: length (u32), type, payload, CRC-32 of type + payload (u32)."""
    return (struct.pack("<I", len(payload)) + type_code + payload
            + struct.pack("<I", crc32(payload, crc32(type_code))))


def _layout_toc(chunks: list[Chunk]) -> bytes:
    """TOC body whose offsets account for its own size (a fixed point of the varint sizes)."""
    toc_size = 0
    while True:
        offset = HEADER_SIZE + toc_size + TOC_CRC_SIZE
        rows = []
        for chunk in chunks:
            rows.append((chunk.type.encode("ascii"), int(chunk.layer), chunk.tile, offset,
                         len(chunk.payload)))
            offset += len(chunk.payload) + FRAME_OVERHEAD
        body = encode_toc_body(rows)
        if len(body) == toc_size:
            return body
        # The size only grows between rounds (offsets only grow), so this terminates.
        toc_size = len(body)


def container_bytes(chunks: Iterable[Chunk], flags: int = 0) -> bytes:
    """The complete .csgs bytes for ``chunks`` (ordered stably by layer: base, color, semantic).

    Raises:
        FormatError: a flag this version does not define, too many chunks, or a TOC that
            would pass the documented limits.
    """
    ordered = sorted(chunks, key=lambda c: int(c.layer))
    if not isinstance(flags, int) or flags & ~KNOWN_FLAGS & 0xFFFF or not 0 <= flags <= 0xFFFF:
        raise FormatError(f"flags {flags!r} set bits that version "
                          f"{MAJOR_VERSION}.{MINOR_VERSION} does not define")
    if len(ordered) > MAX_CHUNKS:
        raise FormatError(f"{len(ordered)} chunks exceed the limit {MAX_CHUNKS}")
    toc_body = _layout_toc(ordered)
    if len(toc_body) > MAX_TOC_SIZE:
        raise FormatError(f"TOC of {len(toc_body)} bytes exceeds the limit {MAX_TOC_SIZE}")
    head = encode_header(len(toc_body), flags) + toc_body
    parts = [head, struct.pack("<I", crc32(head))]
    parts += [encode_frame(c.type.encode("ascii"), c.payload) for c in ordered]
    return b"".join(parts)


def write_container(chunks: Iterable[Chunk], flags: int = 0,
                    path: str | os.PathLike | None = None) -> bytes:
    """Build a .csgs container from ``chunks``; when ``path`` is given also write it there.

    The file is written atomically: the bytes go to a temporary file in the same folder,
    which is flushed to disk and then renamed over ``path``; on any failure the temporary
    file is removed and ``path`` is left as it was.

    Returns:
        The container bytes.

    Raises:
        FormatError: the chunks or flags cannot be written (see :func:`container_bytes`).
        InputError: the file cannot be written (``file=`` names it).
    """
    data = container_bytes(chunks, flags)
    if path is not None:
        write_atomically(path, data)
    return data
