"""Damaged containers: bit flips, byte edits, length-field edits, truncations, insertions.

Whatever the damage, the reader and describe() raise FormatError or succeed; nothing else
escapes, and no read request asks for more bytes than the file holds. Damage is a list of
operations (kind, where, value), so hypothesis can shrink a failure to the fewest edits.
"""

from __future__ import annotations

import contextlib
import random
import struct
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgs_codec.errors import FormatError
from csgs_codec.format import Chunk, describe, read_layers, write_container
from csgs_codec.format.primitives import ByteReader, crc32, encode_varint
from tests.format.samples import GuardedFile, sample_chunks

LAYER_SETS = ((), ("color",), ("color", "semantic"))
_BOUNDARIES = (0, 1, 12, 1 << 31, (1 << 32) - 1)


def _base_files() -> list[bytes]:
    with_unknown = sample_chunks()[:3] + [Chunk("zqxj", 1, b"skip me")] + sample_chunks()[3:]
    return [write_container(sample_chunks()), write_container(with_unknown),
            write_container([Chunk("fill", 0, b"x")]), write_container([])]


BASE_FILES = _base_files()


def length_fields(data: bytes) -> list[tuple[int, int, str]]:
    """(offset, size, kind) of every length-like field of a valid container: toc_size,
    chunk_count, each entry's tile/offset/length varint, each frame_length."""
    container = read_layers(data, ())
    fields = [(12, 4, "u32"), (16, len(encode_varint(len(container.toc))), "varint")]
    for entry in container.toc:
        at = entry.toc_offset + 5
        for value in (entry.tile, entry.offset, entry.length):
            size = len(encode_varint(value))
            fields.append((at, size, "varint"))
            at += size
        fields.append((entry.offset, 4, "u32"))
    return fields


def edit_length_field(data: bytes, which: int, value: int) -> bytes:
    """Replace length-like field number ``which`` of ``data`` (a valid container) with a value
    picked by ``value``: next to the old one, a boundary, or ``value`` itself."""
    fields = length_fields(data)
    offset, size, kind = fields[which % len(fields)]
    old = (struct.unpack_from("<I", data, offset)[0] if kind == "u32"
           else ByteReader(data[offset:offset + size]).varint("field"))
    candidates = (old - 1, old + 1, old * 2, old + 12, *_BOUNDARIES, value)
    new = max(0, candidates[value % len(candidates)])
    encoded = (struct.pack("<I", min(new, (1 << 32) - 1)) if kind == "u32"
               else encode_varint(min(new, (1 << 64) - 1)))
    return data[:offset] + encoded + data[offset + size:]


def reseal(data: bytes) -> bytes:
    """``data`` with the TOC CRC and every reachable frame CRC recomputed, so that damage
    reaches the TOC parser and frame checks instead of stopping at a CRC mismatch."""
    out = bytearray(data)
    if len(out) < 16:
        return data
    toc_end = 16 + struct.unpack_from("<I", out, 12)[0]
    if toc_end + 4 > len(out):
        return data
    struct.pack_into("<I", out, toc_end, crc32(out[:toc_end]))
    pos = toc_end + 4
    while pos + 12 <= len(out):
        end = pos + 8 + struct.unpack_from("<I", out, pos)[0]
        if end + 4 > len(out):
            break
        struct.pack_into("<I", out, end, crc32(out[pos + 4:end]))
        pos = end + 4
    return bytes(out)


def apply_damage(data: bytes, ops: list[tuple[int, int, int]]) -> bytes:
    """Apply damage operations (kind, where, value) to ``data`` in order.

    Kinds: 0 flip bit ``value % 8`` of a byte, 1 set a byte, 2 edit a length field (only on
    the undamaged file), 3 truncate, 4 insert a byte, 5 delete a byte, 6 recompute the TOC
    and frame CRCs. ``where`` picks the position modulo the current length + 1.
    """
    out = data
    for kind, where, value in ops:
        pos = where % (len(out) + 1)
        if kind == 0 and pos < len(out):
            out = out[:pos] + bytes([out[pos] ^ (1 << (value % 8))]) + out[pos + 1:]
        elif kind == 1 and pos < len(out):
            out = out[:pos] + bytes([value % 256]) + out[pos + 1:]
        elif kind == 2 and out is data:
            out = edit_length_field(out, where, value)
        elif kind == 3:
            out = out[:pos]
        elif kind == 4:
            out = out[:pos] + bytes([value % 256]) + out[pos:]
        elif kind == 5 and pos < len(out):
            out = out[:pos] + out[pos + 1:]
        elif kind == 6:
            out = reseal(out)
    return out


def random_damage(rng: random.Random) -> list[tuple[int, int, int]]:
    """One to three random damage operations, then a CRC fix half of the time."""
    ops = [(rng.randrange(6), rng.randrange(1 << 16), rng.randrange(1 << 64))
           for _ in range(rng.choice((1, 1, 1, 2, 3)))]
    return ops + [(6, 0, 0)] if rng.random() < 0.5 else ops


DAMAGE = st.lists(st.tuples(st.integers(0, 6), st.integers(0, 1 << 16),
                            st.integers(0, (1 << 64) - 1)), min_size=1, max_size=4)


def decode_everything(data: bytes) -> None:
    """Read every layer set and describe(verify=True); only FormatError may escape."""
    for layers in LAYER_SETS:
        with contextlib.suppress(FormatError):
            read_layers(data, layers)
    with contextlib.suppress(FormatError):
        describe(data, verify=True)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(base=st.sampled_from(BASE_FILES), ops=DAMAGE)
def test_damaged_containers_raise_only_format_error(base, ops):
    damaged = apply_damage(base, ops)
    decode_everything(damaged)
    guarded = GuardedFile(damaged, forbidden=[])
    with contextlib.suppress(FormatError):
        read_layers(guarded, ("color", "semantic"))
    assert all(n <= len(damaged) for _, n in guarded.reads)


@settings(max_examples=100, deadline=None)
@given(base=st.sampled_from(BASE_FILES[:2]), data=st.data())
def test_every_single_bit_flip_in_header_or_toc_is_detected(base, data):
    toc_end = read_layers(base, ()).header_and_toc_size
    pos = data.draw(st.integers(0, toc_end - 1).filter(lambda p: p not in (9, 10)))
    bit = data.draw(st.integers(0, 7))
    damaged = bytearray(base)
    damaged[pos] ^= 1 << bit  # bytes 9 and 10 (minor version, optional flags) may change
    with pytest.raises(FormatError):
        read_layers(bytes(damaged), ())


def test_every_single_bit_flip_in_a_read_chunk_is_detected():
    base = BASE_FILES[0]
    start = read_layers(base, ()).header_and_toc_size
    for pos in range(start, len(base)):
        for bit in range(8):
            damaged = bytearray(base)
            damaged[pos] ^= 1 << bit
            with pytest.raises(FormatError):
                read_layers(bytes(damaged), ("color", "semantic"))


@pytest.mark.slow
def test_one_hundred_thousand_mutated_inputs_raise_only_format_error():
    rng = random.Random(20261123)
    count = 0
    started = time.perf_counter()
    while count < 100_000:
        decode_everything(apply_damage(rng.choice(BASE_FILES), random_damage(rng)))
        count += 1
    elapsed = time.perf_counter() - started
    print(f"\nmutation fuzz: {count} inputs in {elapsed:.1f} s, no exception but FormatError")
    assert count == 100_000
