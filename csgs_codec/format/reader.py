"""Reading the layers of a .csgs container: only the TOC and the chunks asked for.

A color-only read touches the header, the TOC and the base and color chunk frames, never a
byte of the semantic layer, so it also works on a stream cut right after the color layer.
"""

from __future__ import annotations

from collections.abc import Iterable

from csgs_codec.errors import FormatError
from csgs_codec.format.chunk import Container, TocEntry, to_layer_set
from csgs_codec.format.layout import FRAME_FIELDS, FRAME_TRAILER_FIELDS, Layer
from csgs_codec.format.primitives import ByteReader, crc32
from csgs_codec.format.source import ByteSource, SourceLike, open_source
from csgs_codec.format.toc import read_fields, read_toc


def needed_entries(entries: Iterable[TocEntry], layers: frozenset[Layer]) -> list[TocEntry]:
    """Entries to read: those of the requested layers, minus unknown optional chunks.

    Raises FormatError for an unknown critical chunk in a requested layer.
    """
    out = []
    for entry in entries:
        if entry.layer not in layers:
            continue
        if not entry.known:
            if entry.critical:
                raise FormatError(f"unknown critical chunk in the {entry.layer.label} layer",
                                  chunk=entry.type, offset=entry.toc_offset)
            continue
        out.append(entry)
    return out


def name_source(err: FormatError, source: ByteSource) -> None:
    """Add the source's file name to ``err`` when it has none (for the user's message)."""
    if err.file is None and source.name is not None:
        err.file = source.name
        err.args = (str(err),)


def read_frame(source: ByteSource, entry: TocEntry) -> bytes:
    """The payload of ``entry``'s chunk frame, after checking length, type and CRC.

    Raises:
        FormatError: the source ends inside the frame, or the frame's length or type differ
            from the TOC, or the CRC does not match.
    """
    if entry.end > source.size:
        raise FormatError(f"truncated: the chunk needs bytes up to {entry.end}, the source "
                          f"has {source.size}", chunk=entry.type, offset=source.size)
    reader = ByteReader(source.read(entry.offset, entry.frame_size), entry.offset, entry.type)
    frame = read_fields(reader, FRAME_FIELDS)
    if frame["frame_length"] != entry.length:
        raise reader.error(f"frame length {frame['frame_length']} differs from the TOC length "
                           f"{entry.length}", at=entry.offset)
    if frame["frame_type"] != entry.type.encode("ascii"):
        raise reader.error(f"frame type {frame['frame_type']!r} differs from the TOC",
                           at=entry.offset + 4)
    payload = reader.raw(entry.length, "payload")
    crc_at = reader.offset
    crc = read_fields(reader, FRAME_TRAILER_FIELDS)["crc"]
    if crc32(payload, crc32(frame["frame_type"])) != crc:
        raise reader.error("chunk CRC mismatch", at=crc_at)
    return payload


def read_layers(source: SourceLike,
                layers: Iterable[Layer | int | str] | str = frozenset({"color"})) -> Container:
    """Read the header, the TOC and the chunks of ``layers`` (base is always read).

    Args:
        source: the container as bytes, a path, or a seekable binary file (read from its
            current position).
        layers: layer names ('color', 'semantic', 'base'), Layer values, or a comma-separated
            string. Chunks of other layers are never read; unknown optional chunks are
            skipped without reading their bytes.

    Returns:
        A :class:`Container` with the header fields, every TOC entry and the payloads read.

    Raises:
        FormatError: anything malformed in the header, TOC or the chunks read, including a
            source that ends before the last chunk of a requested layer.
        InputError: ``source`` cannot be opened, or ``layers`` names an unknown layer.
    """
    wanted = to_layer_set(layers)
    src = open_source(source)
    try:
        toc = read_toc(src)
        payloads = {entry.index: read_frame(src, entry)
                    for entry in needed_entries(toc.entries, wanted)}
    except FormatError as err:
        name_source(err, src)
        raise
    finally:
        src.close()
    return Container(toc.major_version, toc.minor_version, toc.flags, toc.entries, payloads,
                     wanted, toc.source_size, toc.header_and_toc_size)
