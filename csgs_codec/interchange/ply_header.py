"""Parsing of PLY headers: format, elements, properties and the byte size they promise.

Only the header is read here; :mod:`csgs_codec.interchange.ply_reader` reads the body. Every size
the header announces is checked against the file size before anything is allocated.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from csgs_codec.errors import InputError

#: Longest header accepted, bytes (real 3DGS headers are about 1.5 KiB).
MAX_HEADER_BYTES = 1 << 20
#: Most properties accepted in one element.
MAX_PROPERTIES = 4096

#: PLY scalar type names (and the common aliases) -> numpy type codes without byte order.
PLY_TYPES = {
    "char": "i1", "int8": "i1",
    "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4",
    "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4",
    "double": "f8", "float64": "f8",
    # Not in the original PLY definition, written by some GPU tools.
    "half": "f2", "float16": "f2",
}

#: The line that ends a header: "end_header" alone on its line (trailing blanks or CR allowed).
_END_HEADER = re.compile(rb"^end_header[ \t\r]*(?:\n|\Z)", re.MULTILINE)

FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}


@dataclass
class PlyProperty:
    """One scalar property: its name and numpy type code (e.g. ``"f4"``); lists are rejected."""

    name: str
    type_code: str


@dataclass
class PlyElement:
    """One element of the header: name, instance count and its scalar properties."""

    name: str
    count: int
    properties: list[PlyProperty] = field(default_factory=list)
    has_list: bool = False

    def dtype(self, byte_order: str) -> np.dtype:
        """Structured numpy dtype of one binary row, packed, in ``byte_order`` ('<' or '>')."""
        return np.dtype([(p.name, byte_order + p.type_code) for p in self.properties])

    @property
    def row_bytes(self) -> int:
        """Bytes per binary row."""
        return sum(np.dtype(p.type_code).itemsize for p in self.properties)


@dataclass
class PlyHeader:
    """A parsed PLY header.

    Attributes:
        format: ``"ascii"``, ``"binary_little_endian"`` or ``"binary_big_endian"``.
        elements: the elements in file order.
        header_bytes: length of the header including the ``end_header`` line, bytes.
    """

    format: str
    elements: list[PlyElement]
    header_bytes: int

    @property
    def byte_order(self) -> str | None:
        """'<' or '>' for binary formats, None for ASCII."""
        return FORMATS[self.format]

    def element(self, name: str) -> PlyElement | None:
        """The element called ``name``, or None."""
        for el in self.elements:
            if el.name == name:
                return el
        return None


def parse_header(data: bytes, source: str | None = None) -> PlyHeader:
    """Parse the header at the start of ``data`` (which may hold only the first bytes).

    Raises:
        InputError: not a PLY, truncated or malformed header; names the line's byte offset.
    """
    if not data:
        raise InputError("empty file", file=source)
    if not data.startswith(b"ply"):
        raise InputError("not a PLY file (does not start with 'ply')", file=source, offset=0)
    # The header ends at the first *line* that is "end_header" ("comment ... end_header"
    # does not end it).
    match = _END_HEADER.search(data, 0, MAX_HEADER_BYTES)
    if match is None:
        if len(data) >= MAX_HEADER_BYTES:
            raise InputError(f"no 'end_header' within the first {MAX_HEADER_BYTES} bytes",
                             file=source, offset=0)
        raise InputError("truncated header (no 'end_header' line)", file=source,
                         offset=len(data))
    end = match.start()
    if not match.group().endswith(b"\n"):
        raise InputError("truncated header ('end_header' line has no newline)", file=source,
                         offset=end)
    header_bytes = match.end()
    try:
        text = data[:end].decode("ascii")
    except UnicodeDecodeError as exc:
        raise InputError("header is not ASCII text", file=source, offset=exc.start) from None

    fmt: str | None = None
    elements: list[PlyElement] = []
    offset = 0
    for number, raw in enumerate(text.split("\n")):
        line_offset = offset
        offset += len(raw) + 1
        words = raw.strip().split()
        if number == 0:
            if words != ["ply"]:
                raise InputError("first line must be 'ply'", file=source, offset=0)
            continue
        if not words or words[0] in ("comment", "obj_info"):
            continue
        keyword = words[0]
        if keyword == "format":
            if len(words) != 3 or words[1] not in FORMATS or words[2] != "1.0":
                raise InputError(f"unsupported format line {raw.strip()!r}", file=source,
                                 offset=line_offset)
            fmt = words[1]
        elif keyword == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise InputError(f"malformed element line {raw.strip()!r}", file=source,
                                 offset=line_offset)
            elements.append(PlyElement(words[1], int(words[2])))
        elif keyword == "property":
            if not elements:
                raise InputError("property before any element", file=source, offset=line_offset)
            el = elements[-1]
            if len(words) >= 2 and words[1] == "list":
                if len(words) != 5:
                    raise InputError(f"malformed list property {raw.strip()!r}", file=source,
                                     offset=line_offset)
                el.has_list = True
                el.properties.append(PlyProperty(words[4], "list"))
                continue
            if len(words) != 3 or words[1] not in PLY_TYPES:
                raise InputError(f"malformed or unknown-type property {raw.strip()!r}",
                                 file=source, offset=line_offset)
            if any(p.name == words[2] for p in el.properties):
                raise InputError("duplicate property", file=source, property=words[2],
                                 offset=line_offset)
            if len(el.properties) >= MAX_PROPERTIES:
                raise InputError(f"more than {MAX_PROPERTIES} properties", file=source,
                                 offset=line_offset)
            el.properties.append(PlyProperty(words[2], PLY_TYPES[words[1]]))
        else:
            raise InputError(f"unknown header keyword {keyword!r}", file=source,
                             offset=line_offset)
    if fmt is None:
        raise InputError("header has no 'format' line", file=source, offset=0)
    return PlyHeader(fmt, elements, header_bytes)
