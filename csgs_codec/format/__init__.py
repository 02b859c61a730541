"""The .csgs bitstream container: bytes only (standard library and numpy, never torch).

Layout (spec/FORMAT.md): 16-byte header, table of contents, then chunk frames in layer
order base, color, semantic. Public API:

- :func:`write_container` / :func:`container_bytes`: chunks -> bytes (and an atomic file).
- :func:`read_layers`: bytes, path or seekable file -> :class:`Container`, reading only the
  TOC and the chunks of the layers asked for.
- :func:`describe` / :func:`format_description`: facts for ``csgs info``.
- :data:`CHUNK_TYPES`: the registry of known chunk types.
- :class:`ByteReader` / :class:`ByteWriter`: bounds-checked primitives for chunk payloads.
"""

from __future__ import annotations

from csgs_codec.format.chunk import Chunk, Container, TocEntry
from csgs_codec.format.chunk_types import CHUNK_TYPES, ChunkType, is_critical
from csgs_codec.format.describe import describe, format_description
from csgs_codec.format.layout import LAYER_NAMES, MAGIC, MAJOR_VERSION, MINOR_VERSION, Layer
from csgs_codec.format.primitives import (
    ByteReader,
    ByteWriter,
    crc32,
    encode_varint,
    zigzag_decode,
    zigzag_encode,
)
from csgs_codec.format.reader import read_layers
from csgs_codec.format.writer import container_bytes, write_container

__all__ = [
    "CHUNK_TYPES",
    "LAYER_NAMES",
    "MAGIC",
    "MAJOR_VERSION",
    "MINOR_VERSION",
    "ByteReader",
    "ByteWriter",
    "Chunk",
    "ChunkType",
    "Container",
    "Layer",
    "TocEntry",
    "container_bytes",
    "crc32",
    "describe",
    "encode_varint",
    "format_description",
    "is_critical",
    "read_layers",
    "write_container",
    "zigzag_decode",
    "zigzag_encode",
]
