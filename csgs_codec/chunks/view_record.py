"""The ``vdis`` chunk: which viewing distribution an encode followed (FORMAT §12.21).

Optional and informative: decoders need nothing from it (a decoder that does not know it skips
it, as the critical bit says); ``csgs info`` reports it. A record that cannot be read does not
make the file invalid: readers report no distribution (§12.21). It records where the views
came from, how many there were and how many Gaussians view pruning left out for them.
"""

from __future__ import annotations

from dataclasses import dataclass

from csgs_codec.format.primitives import ByteReader, ByteWriter

VERSION = 1
#: Source codes of the ``source`` field.
SOURCES = {0: "default-sphere", 1: "cameras"}
#: Longest description, UTF-8 bytes.
MAX_DESCRIPTION = 256


@dataclass(frozen=True)
class ViewRecord:
    """What a ``vdis`` chunk says.

    Attributes:
        source: "default-sphere" or "cameras".
        views: number of views the sensitivities were summed over.
        left_out: Gaussians view pruning removed.
        description: one line, e.g. ``72 views on a sphere at 3 distances``.
    """

    source: str
    views: int
    left_out: int
    description: str

    def to_bytes(self) -> bytes:
        """The chunk payload (the description is cut to 256 UTF-8 bytes at a character)."""
        code = {name: c for c, name in SOURCES.items()}[self.source]
        text = self.description.encode("utf-8")[:MAX_DESCRIPTION]
        out = ByteWriter()
        out.fixed("u8", VERSION)
        out.fixed("u8", code)
        out.varint(self.views)
        out.varint(self.left_out)
        out.byte_string(text.decode("utf-8", "ignore").encode("utf-8"))
        return out.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, base_offset: int = 0) -> ViewRecord:
        """Parse a payload.

        Raises:
            FormatError: unknown version or source, a count over 2^32, a description over
                256 bytes or not UTF-8, or trailing bytes.
        """
        r = ByteReader(data, base_offset=base_offset, chunk="vdis")
        version = r.fixed("u8", "version")
        if version != VERSION:
            raise r.error(f"unknown view-distribution version {version}", at=r.offset - 1)
        code = r.fixed("u8", "source")
        if code not in SOURCES:
            raise r.error(f"unknown view source {code}", at=r.offset - 1)
        views = r.varint("view_count", maximum=1 << 32)
        left_out = r.varint("left_out", maximum=1 << 32)
        raw = r.byte_string("description", maximum=MAX_DESCRIPTION)
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise r.error("description is not UTF-8") from None
        r.expect_end("the view-distribution record")
        return cls(SOURCES[code], views, left_out, text)
