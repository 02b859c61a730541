"""Limits of spec/FORMAT.md §10 are checked before anything is read or allocated."""

from __future__ import annotations

import struct

import pytest

from csgs_codec.errors import FormatError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.format.layout import MAX_CHUNKS, MAX_TOC_SIZE
from csgs_codec.format.primitives import crc32, encode_varint
from tests.format.samples import GuardedFile, sample_chunks


def _resealed(head_and_body: bytes, rest: bytes = b"") -> bytes:
    return head_and_body + struct.pack("<I", crc32(head_and_body)) + rest


def _header(toc_size: int) -> bytes:
    return b"\x89CSG\r\n\x1a\n" + struct.pack("<BBHI", 1, 0, 0, toc_size)


def test_toc_size_over_the_limit_is_rejected_after_reading_only_the_header():
    data = _header(MAX_TOC_SIZE + 1) + bytes(64)
    guarded = GuardedFile(data, forbidden=[(16, len(data))])
    with pytest.raises(FormatError, match="toc_size") as info:
        read_layers(guarded)
    assert info.value.offset == 12


def test_toc_size_past_the_end_of_the_stream_is_rejected_before_reading_the_toc():
    data = _header(MAX_TOC_SIZE) + bytes(64)
    guarded = GuardedFile(data, forbidden=[(16, len(data))])
    with pytest.raises(FormatError, match="truncated") as info:
        read_layers(guarded)
    assert info.value.offset == len(data)


def test_chunk_count_over_the_limit_is_rejected():
    body = encode_varint(MAX_CHUNKS + 1) + bytes(8 * 4)
    with pytest.raises(FormatError, match="exceeds the limit") as info:
        read_layers(_resealed(_header(len(body)) + body))
    assert info.value.offset == 16


def test_chunk_count_larger_than_the_toc_can_hold_is_rejected():
    body = encode_varint(1000) + bytes(16)
    with pytest.raises(FormatError, match="cannot fit"):
        read_layers(_resealed(_header(len(body)) + body))


def test_payload_length_past_the_end_is_rejected_without_a_large_read():
    data = bytearray(write_container([Chunk("fill", 1, b"x" * 100)]))
    container = read_layers(bytes(data))
    entry = container.toc[0]
    # Claim the largest length in both TOC and frame; the TOC CRC is recomputed.
    body = encode_varint(1) + b"fill" + bytes([1]) + encode_varint(0) + encode_varint(
        entry.offset + 4) + encode_varint((1 << 32) - 1)
    frame = struct.pack("<I", (1 << 32) - 1) + bytes(data[entry.offset + 4:])
    damaged = _resealed(_header(len(body)) + body, frame)
    guarded = GuardedFile(damaged, forbidden=[])
    with pytest.raises(FormatError, match="truncated") as info:
        read_layers(guarded)
    assert info.value.chunk == "fill"
    assert max(n for _, n in guarded.reads) <= len(damaged)


def test_reads_of_a_valid_file_never_ask_for_more_than_the_file():
    data = write_container(sample_chunks())
    guarded = GuardedFile(data, forbidden=[])
    read_layers(guarded, ("color", "semantic"))
    assert sum(n for _, n in guarded.reads) == len(data)
