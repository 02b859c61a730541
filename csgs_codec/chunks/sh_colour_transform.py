"""The SH colour transform record `SHXF` (FORMAT §12.24), both directions: a version, then
one transform id per coded SH band (0 as colours, 1 in opponent colours). What the ids mean
to the values is :mod:`csgs_codec.attributes.sh_colour_transform`'s.
"""

from __future__ import annotations

from csgs_codec.attributes.sh_colour_transform import IDENTITY, OPPONENT
from csgs_codec.format.primitives import ByteReader, ByteWriter

#: The record's version.
SHXF_VERSION = 1


def colour_transform_payload(transforms: tuple[int, ...]) -> bytes:
    """The ``SHXF`` payload for one transform id per coded band (bands 1.. in order)."""
    out = ByteWriter()
    out.fixed("u8", SHXF_VERSION)
    out.fixed("u8", len(transforms))
    for transform in transforms:
        out.fixed("u8", transform)
    return out.getvalue()


def parse_colour_transform(data: bytes, offset: int, sh_degree_coded: int) -> tuple[int, ...]:
    """The transform id of each coded band from an ``SHXF`` payload at file ``offset``.

    Raises:
        FormatError: a version other than 1, a band count other than ``sh_degree_coded``
            (or none coded), an unknown id or trailing bytes, at the offending byte.
    """
    r = ByteReader(data, base_offset=offset, chunk="SHXF")
    at = r.offset
    version = r.fixed("u8", "version")
    if version != SHXF_VERSION:
        raise r.error(f"unsupported SH colour transform version {version}", at=at)
    at = r.offset
    count = r.fixed("u8", "band_count")
    if count != sh_degree_coded or count == 0:
        raise r.error(f"the record lists {count} bands, the scene codes "
                      f"{sh_degree_coded}", at=at)
    transforms = []
    for _ in range(count):
        at = r.offset
        transform = r.fixed("u8", "transform")
        if transform not in (IDENTITY, OPPONENT):
            raise r.error(f"unknown SH colour transform {transform}", at=at)
        transforms.append(transform)
    r.expect_end("the SH colour transform record")
    return tuple(transforms)


def read_colour_transform(container, sh_degree_coded: int
                          ) -> tuple[tuple[int, ...], int] | None:
    """(transform id per coded band, the payload's file offset) of ``container``'s SHXF
    chunk for a scene coding ``sh_degree_coded`` bands, or None without one.

    Raises:
        FormatError: a bad record (:func:`parse_colour_transform`).
    """
    if not any(e.type == "SHXF" for e in container.toc):
        return None
    data, offset = container.single_payload("SHXF")
    return parse_colour_transform(data, offset, sh_degree_coded), offset
