"""A mutation operator aimed at the tile index's levels of detail (``TIDX`` version 2,
FORMAT §12.22): rewrite one tile entry's ``level`` or ``parent``, swap two entries' links,
or turn the index into the other version, keeping the rest of the payload well formed.

Byte-level payload edits rarely land on the one ``level`` byte and the ``parent`` varint of an
entry (2 of 27+ bytes, behind a varint count), and almost never leave the rest of the index
readable; this operator edits the parsed entries and writes them back, so the tree checks
(a top-level tile with a parent, a parent of the wrong level, a childless coarse tile, a
version-2 index all of level 0) and the decode of a level whose tiles moved are reached.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, replace

from csgs_codec.format import encode_varint
from tests.fuzz.container_edit import RawChunk

#: Bytes of a tile entry's box: six float32.
BOX_BYTES = 24
#: Levels worth writing: the edges of the 0..15 range and just past it.
LEVEL_VALUES = (0, 1, 2, 3, 14, 15, 16, 255)


@dataclass(frozen=True)
class Entry:
    """One tile entry as parsed: its Gaussian count, box bytes, level and parent field (0:
    none, else 1 + a tile number), as stored."""

    count: int
    box: bytes
    level: int = 0
    link: int = 0


def _varint(data: bytes, at: int) -> tuple[int, int] | None:
    """(value, offset after it) of the LEB128 varint at ``at``, or None when cut short or
    longer than 10 bytes."""
    value = 0
    for k in range(10):
        if at + k >= len(data):
            return None
        byte = data[at + k]
        value |= (byte & 0x7F) << (7 * k)
        if not byte & 0x80:
            return value, at + k + 1
    return None


def parse_entries(payload: bytes) -> tuple[int, list[Entry]] | None:
    """(version, entries) of a ``TIDX`` payload of version 1 or 2 read without any range
    check, or None when it is not one (cut short, unknown version, trailing bytes)."""
    if not payload or payload[0] not in (1, 2):
        return None
    version = payload[0]
    head = _varint(payload, 1)
    if head is None or head[0] > 1 << 16:
        return None
    count, at = head
    entries = []
    for _ in range(count):
        field = _varint(payload, at)
        if field is None or field[1] + BOX_BYTES > len(payload):
            return None
        n, at = field
        box, at = payload[at:at + BOX_BYTES], at + BOX_BYTES
        level = link = 0
        if version == 2:
            if at >= len(payload):
                return None
            level = payload[at]
            field = _varint(payload, at + 1)
            if field is None:
                return None
            link, at = field
        entries.append(Entry(n, box, level, link))
    return (version, entries) if at == len(payload) else None


def write_entries(version: int, entries: list[Entry]) -> bytes:
    """A ``TIDX`` payload of ``version`` holding ``entries`` (levels and parents written in
    version 2 only)."""
    out = bytearray([version]) + encode_varint(len(entries))
    for entry in entries:
        out += encode_varint(entry.count) + entry.box
        if version == 2:
            out += bytes([entry.level & 0xFF]) + encode_varint(entry.link)
    return bytes(out)


def _edit(rng: random.Random, version: int, entries: list[Entry]) -> tuple[str, int] | None:
    """Edit ``entries`` in place; (what was done, the version to write), or None."""
    if not entries:
        return None
    i = rng.randrange(len(entries))
    kind = rng.randrange(5)
    if version == 1 or kind == 4:  # the other version: levels added, or dropped
        if version == 2:
            return "to_version_1", 1
        top = rng.choice((1, 2))
        for k in range(len(entries)):  # a plausible tree: tile 0 the root of the rest
            entries[k] = replace(entries[k], level=top if k == 0 else rng.choice((0, top - 1)),
                                 link=0 if k == 0 else 1)
        return "to_version_2", 2
    if kind == 0:
        old = entries[i].level
        new = rng.choice((max(old - 1, 0), old + 1) + LEVEL_VALUES)
        entries[i] = replace(entries[i], level=new)
        return "level", 2
    if kind == 1:
        choices = (0, 1 + rng.randrange(len(entries)), 1 + i, len(entries),
                   len(entries) + 1, rng.choice((1 << 16, (1 << 32) - 1, 1 << 63)))
        entries[i] = replace(entries[i], link=rng.choice(choices))
        return "parent", 2
    if kind == 2:
        j = rng.randrange(len(entries))
        a, b = entries[i], entries[j]
        entries[i], entries[j] = replace(a, link=b.link), replace(b, link=a.link)
        return "swap_parents", 2
    j = rng.randrange(len(entries))
    a, b = entries[i], entries[j]  # two tiles trade places in the tree
    entries[i], entries[j] = (replace(a, level=b.level, link=b.link),
                              replace(b, level=a.level, link=a.link))
    return "swap_links", 2


def edit_tile_index(rng: random.Random, chunks: list[RawChunk], donors) -> str | None:
    """Chunk operator: rewrite the entries of the first ``TIDX`` chunk of ``chunks`` (see the
    module docstring); None (nothing done) when the list has no readable tile index."""
    at = next((k for k, c in enumerate(chunks) if c.type == b"TIDX"), None)
    if at is None:
        return None
    parsed = parse_entries(chunks[at].payload)
    if parsed is None:
        return None
    version, entries = parsed
    done = _edit(rng, version, entries)
    if done is None:
        return None
    name, written = done
    chunks[at] = replace(chunks[at], payload=write_entries(written, entries))
    return f"tile_index_edit:{name}"
