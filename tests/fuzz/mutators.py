"""Mutations of seed .csgs files: payload edits, chunk swaps, TOC and frame lies, byte flips,
truncation; CRCs recomputed for most mutants.

A mutant is made in three stages, each applying zero or more operators (at least one in all):

1. chunk operators edit the chunk list (payload bytes, splices from another seed, swaps,
   drops, duplicates, a tile index's levels and parents: tests/fuzz/tile_index_edit.py);
   the container is then laid out truthfully around the new chunks;
2. layout operators make the header, TOC or frames lie (lengths, offsets, layers, types,
   tiles, versions, flags, CRCs);
3. byte operators flip or set bytes anywhere in the file, or cut it short.

Then, unless a CRC lie was asked for, :func:`~tests.fuzz.container_edit.repair_crcs` runs
with probability :data:`REPAIR_PROBABILITY`. Everything is drawn from one
``random.Random``, so a mutant is a pure function of (seed files, index, campaign seed).
"""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from csgs_codec.format import encode_varint
from tests.fuzz.container_edit import Layout, RawChunk, layout_of, repair_crcs
from tests.fuzz.seeds import Seed
from tests.fuzz.tile_index_edit import edit_tile_index

#: Share of mutants whose CRCs are recomputed after mutation.
REPAIR_PROBABILITY = 0.9
#: Bytes that tend to sit on boundaries: zero, one, sign and continuation bits, all ones.
INTERESTING_BYTES = (0x00, 0x01, 0x02, 0x03, 0x04, 0x3F, 0x40, 0x7F, 0x80, 0x81, 0xFE, 0xFF)
#: Values worth writing as varints or length fields.
INTERESTING_VALUES = (0, 1, 2, 3, 4, 7, 8, 63, 64, 127, 128, 255, 256, 1 << 15, (1 << 16) - 1,
                      1 << 16, 1 << 20, (1 << 26) + 1, 1 << 28, (1 << 31) - 1, 1 << 31,
                      (1 << 32) - 1, 1 << 32, (1 << 53) + 1, (1 << 63), (1 << 64) - 1)
#: Payload bytes before this offset (counts, modes, indices) are chosen more often.
HEAD_BYTES = 24


@dataclass(frozen=True)
class Mutant:
    """A mutated file: its bytes, the seed it came from and the operators applied, in order."""

    data: bytes
    seed: str
    operators: tuple[str, ...]


# ---------------------------------------------------------------- payload helpers
def byte_position(rng: random.Random, size: int, head: int = HEAD_BYTES) -> int:
    """A byte position in [0, size), the first ``head`` bytes drawn half the time (where
    headers and counts sit)."""
    if size <= 0:
        return 0
    if rng.random() < 0.5:
        return rng.randrange(min(size, head))
    return rng.randrange(size)


def _value(rng: random.Random) -> int:
    if rng.random() < 0.6:
        return rng.choice(INTERESTING_VALUES)
    return rng.getrandbits(rng.choice((7, 14, 21, 32, 64)))


def _flip_bits(rng: random.Random, data: bytes) -> bytes:
    if not data:
        return data
    out = bytearray(data)
    for _ in range(rng.choice((1, 1, 1, 2, 3, 4))):
        at = byte_position(rng, len(out))
        out[at] ^= 1 << rng.randrange(8)
    return bytes(out)


def _set_bytes(rng: random.Random, data: bytes) -> bytes:
    if not data:
        return data
    out = bytearray(data)
    for _ in range(rng.choice((1, 1, 2, 3))):
        out[byte_position(rng, len(out))] = (rng.choice(INTERESTING_BYTES) if rng.random() < 0.7
                                         else rng.randrange(256))
    return bytes(out)


def _resize(rng: random.Random, data: bytes) -> bytes:
    kind = rng.randrange(4)
    at = byte_position(rng, len(data) + 1)
    if kind == 0:  # cut the payload short
        return data[:at]
    if kind == 1:  # append bytes
        return data + rng.randbytes(rng.choice((1, 2, 4, 16)))
    if kind == 2:  # delete a slice
        return data[:at] + data[at + rng.choice((1, 2, 4, 8, 64)):]
    return data[:at] + rng.randbytes(rng.choice((1, 2, 4, 8))) + data[at:]  # insert bytes


def _write_varint(rng: random.Random, data: bytes) -> bytes:
    at = byte_position(rng, len(data) + 1)
    old = rng.choice((0, 1, 1, 2, 4))  # bytes the new varint replaces
    return data[:at] + encode_varint(_value(rng)) + data[at + old:]


def _write_word(rng: random.Random, data: bytes) -> bytes:
    if len(data) < 4:
        return data
    at = rng.randrange(len(data) - 3)
    return data[:at] + rng.getrandbits(32).to_bytes(4, "little") + data[at + 4:]


PAYLOAD_EDITS: dict[str, Callable[[random.Random, bytes], bytes]] = {
    "payload_bit_flip": _flip_bits,
    "payload_byte_set": _set_bytes,
    "payload_resize": _resize,
    "payload_varint": _write_varint,
    "payload_word": _write_word,
}


# ---------------------------------------------------------------- chunk operators
def _edit_payload(rng, chunks, donors):
    if not chunks:
        return None
    name = rng.choice(sorted(PAYLOAD_EDITS))
    i = rng.randrange(len(chunks))
    chunks[i] = replace(chunks[i], payload=PAYLOAD_EDITS[name](rng, chunks[i].payload))
    return f"{name}:{chunks[i].type.decode('latin-1')}"


def _splice(rng, chunks, donors):
    """Replace a payload by the payload of the same chunk type in another seed."""
    if not chunks:
        return None
    i = rng.randrange(len(chunks))
    same = [c for d in donors for c in d.chunks if c.type == chunks[i].type]
    if not same:
        return None
    chunks[i] = replace(chunks[i], payload=rng.choice(same).payload)
    return f"splice:{chunks[i].type.decode('latin-1')}"


def _swap(rng, chunks, donors):
    if len(chunks) < 2:
        return None
    i, j = rng.sample(range(len(chunks)), 2)
    if rng.random() < 0.5:
        chunks[i], chunks[j] = chunks[j], chunks[i]
        return "chunk_swap"
    a, b = chunks[i], chunks[j]
    chunks[i], chunks[j] = replace(a, payload=b.payload), replace(b, payload=a.payload)
    return "payload_swap"


def _drop(rng, chunks, donors):
    if not chunks:
        return None
    del chunks[rng.randrange(len(chunks))]
    return "chunk_drop"


def _duplicate(rng, chunks, donors):
    if not chunks:
        return None
    i = rng.randrange(len(chunks))
    at = i + 1 if rng.random() < 0.8 else rng.randrange(len(chunks) + 1)
    chunks.insert(at, chunks[i])
    return "chunk_duplicate"


CHUNK_OPERATORS = (_edit_payload, _edit_payload, _edit_payload, _edit_payload, _splice, _swap,
                   _drop, _duplicate, edit_tile_index)


# ---------------------------------------------------------------- layout operators
def _row(rng: random.Random, layout: Layout) -> list | None:
    return rng.choice(layout.rows) if layout.rows else None


def _small_change(rng: random.Random, value: int) -> int:
    if rng.random() < 0.3:
        return _value(rng)
    return max(0, value + rng.choice((-8, -4, -1, 1, 4, 8)))


def _toc_length_lie(rng, layout):
    row = _row(rng, layout)
    if row is None:
        return None
    row[4] = _small_change(rng, row[4])
    if rng.random() < 0.5:  # make the frame agree, so only the offsets after it are wrong
        i = layout.rows.index(row)
        layout.frames[i].length = row[4]
    return "toc_length_lie"


def _frame_length_lie(rng, layout):
    if not layout.frames:
        return None
    frame = rng.choice(layout.frames)
    frame.length = _small_change(rng, frame.length)
    return "frame_length_lie"


def _toc_offset_lie(rng, layout):
    row = _row(rng, layout)
    if row is None:
        return None
    others = [r[3] for r in layout.rows if r is not row]
    row[3] = rng.choice(others) if others and rng.random() < 0.5 else _small_change(rng, row[3])
    return "toc_offset_lie"


def _toc_field_lie(rng, layout):
    row = _row(rng, layout)
    if row is None:
        return None
    field = rng.randrange(3)
    if field == 0:
        row[1] = rng.choice((0, 1, 2, 2, 3, 255))
        return "toc_layer_lie"
    if field == 1:
        row[2] = _value(rng)
        return "toc_tile_lie"
    donor = rng.choice(layout.rows)[0]
    row[0] = bytes([donor[0] ^ 0x20]) + donor[1:] if rng.random() < 0.3 else donor
    if rng.random() < 0.5:
        layout.frames[layout.rows.index(row)].type = row[0]
    return "toc_type_lie"


def _toc_row_count_lie(rng, layout):
    if not layout.rows:
        return None
    if rng.random() < 0.5:
        del layout.rows[rng.randrange(len(layout.rows))]
    else:
        layout.rows.append(list(rng.choice(layout.rows)))
    return "toc_row_count_lie"


def _header_lie(rng, layout):
    field = rng.randrange(4)
    if field == 0:
        body = len(layout.to_bytes()) - 20 - sum(len(f.to_bytes()) for f in layout.frames)
        layout.toc_size = _small_change(rng, body)
        return "toc_size_lie"
    if field == 1:
        layout.minor = rng.randrange(256)
        return "minor_version"
    if field == 2:
        layout.flags = 1 << rng.randrange(16)
        return "flag_bit"
    layout.major = rng.choice((0, 2, 255))
    return "major_version"


def _crc_lie(rng, layout):
    if rng.random() < 0.5 or not layout.frames:
        layout.toc_crc = rng.getrandbits(32)
    else:
        rng.choice(layout.frames).crc = rng.getrandbits(32)
    return "crc_lie"


LAYOUT_OPERATORS = (_toc_length_lie, _frame_length_lie, _toc_offset_lie, _toc_field_lie,
                    _toc_row_count_lie, _header_lie, _crc_lie)


# ---------------------------------------------------------------- byte operators
def _truncate(rng: random.Random, data: bytes) -> bytes:
    return data[:rng.randrange(len(data) + 1)]


BYTE_OPERATORS = {"bit_flip": lambda rng, data: _flip_bits_anywhere(rng, data),
                  "byte_set": lambda rng, data: _set_bytes_anywhere(rng, data),
                  "truncate": _truncate}


def _flip_bits_anywhere(rng: random.Random, data: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(rng.choice((1, 1, 2, 4))):
        out[rng.randrange(len(out))] ^= 1 << rng.randrange(8)
    return bytes(out)


def _set_bytes_anywhere(rng: random.Random, data: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(rng.choice((1, 1, 2))):
        out[rng.randrange(len(out))] = rng.choice(INTERESTING_BYTES)
    return bytes(out)


# ---------------------------------------------------------------- the pipeline
def _stage_counts(rng: random.Random) -> tuple[int, int, int]:
    """How many chunk, layout and byte operators to apply (at least one in all)."""
    while True:
        counts = (rng.choice((0, 1, 1, 1, 2, 3)), rng.choice((0, 0, 0, 1)),
                  rng.choice((0, 0, 0, 1)))
        if sum(counts):
            return counts


def mutate(seed: Seed, rng: random.Random, donors: Sequence[Seed]) -> Mutant:
    """One mutant of ``seed``; ``donors`` supply payloads for splices."""
    n_chunk, n_layout, n_byte = _stage_counts(rng)
    names: list[str] = []
    chunks: list[RawChunk] = list(seed.chunks)
    for _ in range(n_chunk):
        name = rng.choice(CHUNK_OPERATORS)(rng, chunks, donors)
        if name:
            names.append(name)
    layout = layout_of(chunks)
    for _ in range(n_layout):
        name = rng.choice(LAYOUT_OPERATORS)(rng, layout)
        if name:
            names.append(name)
    data = layout.to_bytes()
    for _ in range(n_byte):
        name = rng.choice(sorted(BYTE_OPERATORS))
        data = BYTE_OPERATORS[name](rng, data)
        names.append(name)
    if "crc_lie" not in names and rng.random() < REPAIR_PROBABILITY:
        data = repair_crcs(data)
        names.append("crc_repaired")
    return Mutant(data, seed.name, tuple(names))
