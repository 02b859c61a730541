"""Parsing and validating the header and table of contents (spec/FORMAT.md §4-§5).

Reads exactly ``16 + toc_size + 4`` bytes of the source, after checking that ``toc_size``
is within the limits and that the source holds that many bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

from csgs_codec.errors import FormatError
from csgs_codec.format.chunk import TocEntry
from csgs_codec.format.chunk_types import CHUNK_TYPES, is_valid_type_code
from csgs_codec.format.layout import (
    FRAME_OVERHEAD,
    HEADER_FIELDS,
    HEADER_SIZE,
    KNOWN_FLAGS,
    MAGIC,
    MAJOR_VERSION,
    MAX_CHUNKS,
    MAX_PAYLOAD_SIZE,
    MAX_TILE,
    MAX_TOC_SIZE,
    RESERVED_FLAGS_MASK,
    TOC_CRC_SIZE,
    TOC_ENTRY_FIELDS,
    TOC_FIELDS,
    TOC_TRAILER_FIELDS,
    Field,
    Layer,
)
from csgs_codec.format.primitives import ByteReader, crc32
from csgs_codec.format.source import ByteSource

#: Fewest bytes a TOC entry can take: type (4), layer (1) and three 1-byte varints.
MIN_TOC_ENTRY_SIZE = 8

_LAYERS = tuple(Layer)
_MAX_LAYER = max(Layer)
_VARINT_LIMITS = {"chunk_count": MAX_CHUNKS, "tile": MAX_TILE, "length": MAX_PAYLOAD_SIZE}


@dataclass(frozen=True)
class TableOfContents:
    """Header fields and TOC entries of a container, validated.

    Attributes:
        major_version, minor_version, flags: header fields.
        entries: the TOC entries in file order.
        header_and_toc_size: bytes of header + TOC body + TOC CRC (= first chunk offset).
        source_size: bytes available in the source.
    """

    major_version: int
    minor_version: int
    flags: int
    entries: tuple[TocEntry, ...]
    header_and_toc_size: int
    source_size: int

    @property
    def file_size(self) -> int:
        """Bytes of the complete file the TOC describes."""
        return self.entries[-1].end if self.entries else self.header_and_toc_size


def _compile_field(field: Field):
    """A function reading ``field`` from a ByteReader (built once per field, for speed)."""
    name = field.name
    if field.kind.startswith("bytes"):
        size = int(field.size_text)
        return lambda reader: reader.raw(size, name)
    if field.kind == "varint":
        limit = _VARINT_LIMITS.get(name, (1 << 64) - 1)
        return lambda reader: reader.varint(name, limit)
    kind = field.kind
    return lambda reader: reader.fixed(kind, name)


_COMPILED: dict[Field, object] = {}


def read_fields(reader: ByteReader, fields: tuple[Field, ...]) -> dict[str, int | bytes]:
    """Read ``fields`` in order from ``reader``; returns name -> value (bytes for raw fields)."""
    out = {}
    for field in fields:
        read = _COMPILED.get(field)
        if read is None:
            read = _COMPILED[field] = _compile_field(field)
        out[field.name] = read(reader)
    return out


def _read_header_bytes(source: ByteSource) -> bytes:
    """The 16 header bytes, after checking the magic in whatever part of them is present."""
    present = source.read(0, min(source.size, HEADER_SIZE))
    for i, byte in enumerate(present[:len(MAGIC)]):
        if byte != MAGIC[i]:
            raise FormatError(f"not a .csgs file: magic byte {i} is 0x{byte:02x}, expected "
                              f"0x{MAGIC[i]:02x}", offset=i)
    if source.size < HEADER_SIZE:
        raise FormatError(f"truncated: the {HEADER_SIZE}-byte header needs bytes up to "
                          f"{HEADER_SIZE}, the source has {source.size}", offset=source.size)
    return present


def _check_header(header: dict[str, int | bytes]) -> None:
    if header["major_version"] != MAJOR_VERSION:
        raise FormatError(f"major version {header['major_version']} is not supported "
                          f"(this decoder reads {MAJOR_VERSION}.x)", offset=8)
    unknown = header["flags"] & RESERVED_FLAGS_MASK & ~KNOWN_FLAGS
    if unknown:
        raise FormatError(f"reserved flag bits 0x{unknown:04x} are set", offset=10)
    if not 1 <= header["toc_size"] <= MAX_TOC_SIZE:
        raise FormatError(f"toc_size {header['toc_size']} is outside 1..{MAX_TOC_SIZE}",
                          offset=12)


def _parse_entries(reader: ByteReader, first_offset: int) -> tuple[TocEntry, ...]:
    count = read_fields(reader, TOC_FIELDS)["chunk_count"]
    if count > reader.remaining // MIN_TOC_ENTRY_SIZE:
        raise reader.error(f"chunk_count {count} cannot fit in the {reader.remaining} TOC "
                           f"bytes that remain", at=HEADER_SIZE)
    entries: list[TocEntry] = []
    expected_offset = first_offset
    previous_layer = Layer.BASE
    type_field, other_fields = TOC_ENTRY_FIELDS[:1], TOC_ENTRY_FIELDS[1:]
    for index in range(count):
        entry_offset = reader.offset
        type_code = read_fields(reader, type_field)["type"]
        if not is_valid_type_code(type_code):
            raise reader.error(f"TOC entry {index}: type {type_code!r} is not four ASCII "
                               f"letters", at=entry_offset)
        code = type_code.decode("ascii")
        reader.chunk = code  # errors in the rest of the entry name its chunk type
        raw = read_fields(reader, other_fields)
        reader.chunk = None
        layer_at = entry_offset + 4
        if raw["layer"] > _MAX_LAYER:
            raise FormatError(f"TOC entry {index}: layer {raw['layer']} is not 0, 1 or 2",
                              chunk=code, offset=layer_at)
        layer = _LAYERS[raw["layer"]]
        if layer < previous_layer:
            raise FormatError(f"TOC entry {index}: {layer.label} chunk after a "
                              f"{previous_layer.label} chunk (layers must be in order)",
                              chunk=code, offset=layer_at)
        known = CHUNK_TYPES.get(code)
        if known is not None and known.layer is not None and known.layer != layer:
            raise FormatError(f"TOC entry {index}: chunk type belongs to the "
                              f"{known.layer.label} layer, not {layer.label}",
                              chunk=code, offset=layer_at)
        if raw["offset"] != expected_offset:
            raise FormatError(f"TOC entry {index}: offset {raw['offset']} is not the end of "
                              f"the previous chunk ({expected_offset})",
                              chunk=code, offset=entry_offset)
        entries.append(TocEntry(index, code, layer, raw["tile"], raw["offset"], raw["length"],
                                entry_offset))
        expected_offset += raw["length"] + FRAME_OVERHEAD
        previous_layer = layer
    reader.expect_end("the TOC")
    return tuple(entries)


def read_toc(source: ByteSource) -> TableOfContents:
    """Read and validate the header and TOC of ``source``.

    Raises:
        FormatError: bad magic, unsupported major version, unknown critical flag, a TOC
            outside the limits or cut short, a TOC CRC mismatch, a malformed entry, or bytes
            after the last chunk the TOC lists.
    """
    header_bytes = _read_header_bytes(source)
    header = read_fields(ByteReader(header_bytes), HEADER_FIELDS)
    _check_header(header)
    toc_size = header["toc_size"]
    total = HEADER_SIZE + toc_size + TOC_CRC_SIZE
    if total > source.size:
        raise FormatError(f"truncated: the TOC needs bytes up to {total}, the source has "
                          f"{source.size}", offset=source.size)
    toc_bytes = source.read(HEADER_SIZE, toc_size + TOC_CRC_SIZE)
    trailer = read_fields(ByteReader(toc_bytes[toc_size:], HEADER_SIZE + toc_size),
                          TOC_TRAILER_FIELDS)
    body = toc_bytes[:toc_size]
    if crc32(body, crc32(header_bytes)) != trailer["toc_crc"]:
        raise FormatError("TOC CRC mismatch (header or TOC damaged)",
                          offset=HEADER_SIZE + toc_size)
    entries = _parse_entries(ByteReader(body, HEADER_SIZE), total)
    toc = TableOfContents(header["major_version"], header["minor_version"], header["flags"],
                          entries, total, source.size)
    if source.size > toc.file_size:
        raise FormatError(f"{source.size - toc.file_size} bytes follow the last chunk",
                          offset=toc.file_size)
    return toc
