"""Value types of the container: a chunk to write, a TOC entry, and a container read back."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.chunk_types import CHUNK_TYPES, check_type_code, is_critical
from csgs_codec.format.layout import FRAME_OVERHEAD, MAX_PAYLOAD_SIZE, MAX_TILE, Layer


def to_layer(value: Layer | int | str) -> Layer:
    """A :class:`Layer` from a Layer, its number (0..2) or its name ('base', 'color', ...)."""
    if isinstance(value, Layer):
        return value
    if isinstance(value, str):
        try:
            return Layer[value.upper()]
        except KeyError:
            raise InputError(f"unknown layer {value!r}; use base, color or semantic") from None
    if isinstance(value, int) and not isinstance(value, bool) and value in Layer._value2member_map_:
        return Layer(value)
    raise InputError(f"unknown layer {value!r}; use base, color or semantic")


def to_layer_set(layers: Iterable[Layer | int | str] | str) -> frozenset[Layer]:
    """The set of layers named by ``layers`` plus :attr:`Layer.BASE`, which is always read."""
    if isinstance(layers, str):
        layers = [part for part in layers.split(",") if part.strip()]
    return frozenset({Layer.BASE, *(to_layer(x.strip() if isinstance(x, str) else x)
                                    for x in layers)})


@dataclass(frozen=True)
class Chunk:
    """One chunk: a 4-letter type, its layer, its tile and its payload bytes.

    ``critical`` follows from the type's first letter (upper case = critical).
    """

    type: str
    layer: Layer
    payload: bytes
    tile: int = 0

    def __post_init__(self) -> None:
        check_type_code(self.type)
        object.__setattr__(self, "layer", to_layer(self.layer))
        object.__setattr__(self, "payload", bytes(self.payload))
        if not isinstance(self.tile, int) or not 0 <= self.tile <= MAX_TILE:
            raise FormatError(f"tile {self.tile!r} is outside 0..{MAX_TILE}", chunk=self.type)
        if len(self.payload) > MAX_PAYLOAD_SIZE:
            raise FormatError(f"payload of {len(self.payload)} bytes exceeds the limit "
                              f"{MAX_PAYLOAD_SIZE}", chunk=self.type)
        known = CHUNK_TYPES.get(self.type)
        if known is not None and known.layer is not None and known.layer != self.layer:
            raise FormatError(f"chunk type belongs to the {known.layer.label} layer, "
                              f"not {self.layer.label}", chunk=self.type)

    @property
    def critical(self) -> bool:
        """True when a decoder that does not know this type must reject its layer."""
        return is_critical(self.type)


@dataclass(frozen=True)
class TocEntry:
    """One table-of-contents entry: where a chunk frame is and what it holds.

    Attributes:
        index: position in the TOC (0-based; also the file order).
        type: 4-letter chunk type.
        layer: the chunk's layer.
        tile: spatial tile number (0 in a single-tile file).
        offset: absolute byte offset of the chunk frame (its length field).
        length: payload bytes (the frame is ``length + 12`` bytes).
        toc_offset: absolute byte offset of this entry inside the TOC.
    """

    index: int
    type: str
    layer: Layer
    tile: int
    offset: int
    length: int
    toc_offset: int

    @property
    def critical(self) -> bool:
        """True when the type's first letter is upper case."""
        return is_critical(self.type)

    @property
    def known(self) -> bool:
        """True when the type is in the chunk-type registry."""
        return self.type in CHUNK_TYPES

    @property
    def frame_size(self) -> int:
        """Bytes the chunk occupies in the file: length field, type, payload and CRC."""
        return self.length + FRAME_OVERHEAD

    @property
    def end(self) -> int:
        """Absolute offset just past the chunk's CRC."""
        return self.offset + self.frame_size


@dataclass(frozen=True)
class Container:
    """What :func:`~csgs_codec.format.reader.read_layers` read from a .csgs source.

    Attributes:
        major_version, minor_version, flags: header fields.
        toc: every TOC entry, in file order (read or not).
        payloads: payload bytes by TOC index, for the chunks that were read: those of the
            layers read whose type is registered (unknown optional chunks are skipped; an
            unknown critical chunk in a layer read is an error).
        layers_read: the layers decoded (always includes base).
        source_size: bytes the source holds (may be less than :attr:`file_size` for a stream
            cut after the layers read).
        header_and_toc_size: bytes of header, TOC and TOC CRC (the offset of the first chunk).
    """

    major_version: int
    minor_version: int
    flags: int
    toc: tuple[TocEntry, ...]
    payloads: dict[int, bytes] = field(repr=False)
    layers_read: frozenset[Layer]
    source_size: int
    header_and_toc_size: int

    @property
    def version(self) -> tuple[int, int]:
        """(major, minor)."""
        return (self.major_version, self.minor_version)

    @property
    def file_size(self) -> int:
        """Bytes of the complete file the TOC describes."""
        return self.toc[-1].end if self.toc else self.header_and_toc_size

    @property
    def complete(self) -> bool:
        """True when the source holds every chunk the TOC lists."""
        return self.source_size >= self.file_size

    def layer_end(self, layer: Layer | int | str) -> int:
        """Absolute offset where ``layer`` (and every layer before it) ends."""
        wanted = to_layer(layer)
        end = self.header_and_toc_size
        for entry in self.toc:
            if entry.layer <= wanted:
                end = entry.end
        return end

    def chunks(self, layer: Layer | int | str | None = None) -> list[Chunk]:
        """The chunks read (optionally only those of ``layer``), in file order."""
        wanted = None if layer is None else to_layer(layer)
        return [Chunk(e.type, e.layer, self.payloads[e.index], e.tile) for e in self.toc
                if e.index in self.payloads and (wanted is None or e.layer == wanted)]

    def single_payload(self, code: str) -> tuple[bytes, int]:
        """(payload, absolute offset of the payload) of the one chunk of type ``code``
        (any tile: a tile's decoder reads a container of that tile's chunks).

        Raises:
            FormatError: the chunk is missing, appears more than once, or was cut off.
        """
        entries = [e for e in self.toc if e.type == code]
        if not entries:
            raise FormatError(f"required chunk {code} is missing", chunk=code)
        if len(entries) > 1:
            raise FormatError(f"chunk {code} appears {len(entries)} times", chunk=code,
                              offset=entries[1].offset)
        entry = entries[0]
        if entry.index not in self.payloads:
            raise FormatError(f"chunk {code} is cut off (stream truncated)", chunk=code,
                              offset=entry.offset)
        return bytes(self.payloads[entry.index]), entry.offset + 8

    def refuse_chunk(self, code: str, why: str) -> None:
        """Raise FormatError at the first ``code`` chunk when there is one (it must not be
        there, for reason ``why``)."""
        entry = next((e for e in self.toc if e.type == code), None)
        if entry is not None:
            raise FormatError(f"unexpected {code} chunk: {why}", chunk=code,
                              offset=entry.offset)

    def payload(self, type: str, tile: int = 0) -> bytes:
        """The payload of the single chunk ``type`` in ``tile``.

        Raises:
            FormatError: no such chunk was read, or there is more than one.
        """
        found = [e for e in self.toc
                 if e.type == type and e.tile == tile and e.index in self.payloads]
        if len(found) != 1:
            what = "missing" if not found else f"present {len(found)} times"
            raise FormatError(f"chunk {what} in tile {tile}", chunk=type,
                              offset=found[1].offset if len(found) > 1 else None)
        return self.payloads[found[0].index]
