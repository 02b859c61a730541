"""Fixed facts of the .csgs layout: magic, versions, layers, flags, limits and field tables.

The field tables (:data:`HEADER_FIELDS`, :data:`TOC_FIELDS`, :data:`TOC_ENTRY_FIELDS`,
:data:`FRAME_FIELDS`) drive the reader, and a test checks that each field appears with the
same name, offset and size in the byte tables of spec/FORMAT.md.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

#: 8-byte signature (spec/FORMAT.md §3): 0x89, "CSG", CR LF, ^Z, LF.
MAGIC = b"\x89CSG\r\n\x1a\n"
#: The major version this code reads and writes; any other major is rejected.
MAJOR_VERSION = 1
#: The minor version this code writes; higher minors of the same major are read.
MINOR_VERSION = 0

#: Header flags (u16). Bits 0-7 are optional (a minor version may define them; decoders ignore
#: unknown ones), bits 8-15 are reserved and must be zero. Version 1.0 defines none.
OPTIONAL_FLAGS_MASK = 0x00FF
RESERVED_FLAGS_MASK = 0xFF00
KNOWN_FLAGS = 0x0000

#: Bytes of the fixed header, of the TOC CRC and of a chunk frame around its payload.
HEADER_SIZE = 16
TOC_CRC_SIZE = 4
FRAME_OVERHEAD = 12

#: Decoder limits (spec/FORMAT.md §10), all checked before anything is allocated.
MAX_CHUNKS = 65_535
MAX_TOC_SIZE = 4 * 1024 * 1024
MAX_TILE = (1 << 32) - 1
MAX_PAYLOAD_SIZE = (1 << 32) - 1


class Layer(enum.IntEnum):
    """Layers in file order; a chunk's layer never depends on a later layer's bytes."""

    BASE = 0
    COLOR = 1
    SEMANTIC = 2

    @property
    def label(self) -> str:
        """Lower-case name used in APIs and JSON: 'base', 'color' or 'semantic'."""
        return LAYER_NAMES[self]


LAYER_NAMES = ("base", "color", "semantic")


@dataclass(frozen=True)
class Field:
    """One field of a byte table: its name, offset (None when variable) and encoding kind.

    ``kind`` is ``bytesN`` (N raw bytes), ``u8``/``u16``/``u32`` (little-endian unsigned)
    or ``varint`` (unsigned LEB128).
    """

    name: str
    offset: int | None
    kind: str

    @property
    def size_text(self) -> str:
        """The size as written in the spec's byte tables, e.g. '8', '2' or 'varint'."""
        if self.kind.startswith("bytes"):
            return self.kind[len("bytes"):]
        return {"u8": "1", "u16": "2", "u32": "4", "varint": "varint"}[self.kind]


HEADER_FIELDS = (
    Field("magic", 0, "bytes8"),
    Field("major_version", 8, "u8"),
    Field("minor_version", 9, "u8"),
    Field("flags", 10, "u16"),
    Field("toc_size", 12, "u32"),
)
TOC_FIELDS = (
    Field("chunk_count", 0, "varint"),
)
TOC_ENTRY_FIELDS = (
    Field("type", None, "bytes4"),
    Field("layer", None, "u8"),
    Field("tile", None, "varint"),
    Field("offset", None, "varint"),
    Field("length", None, "varint"),
)
TOC_TRAILER_FIELDS = (
    Field("toc_crc", None, "u32"),
)
FRAME_FIELDS = (
    Field("frame_length", 0, "u32"),
    Field("frame_type", 4, "bytes4"),
)
FRAME_TRAILER_FIELDS = (
    Field("crc", None, "u32"),
)
