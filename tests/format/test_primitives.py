"""Rules of spec/FORMAT.md §2: varints, zigzag, fixed ints, byte strings, CRC-32."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import (
    ByteReader,
    ByteWriter,
    crc32,
    encode_varint,
    zigzag_decode,
    zigzag_encode,
)


@given(st.integers(0, (1 << 64) - 1))
def test_varint_round_trips_every_u64(value):
    encoded = encode_varint(value)
    reader = ByteReader(encoded)
    assert reader.varint("v") == value
    assert reader.remaining == 0
    assert len(encoded) == max(1, -(-value.bit_length() // 7))


@pytest.mark.parametrize(("value", "encoded"), [
    (0, "00"), (127, "7f"), (128, "8001"), (300, "ac02"), ((1 << 32) - 1, "ffffffff0f")])
def test_varint_matches_the_spec_examples(value, encoded):
    assert encode_varint(value).hex() == encoded


@pytest.mark.parametrize("raw", ["8000", "ff00", "808000"])
def test_varint_not_in_shortest_form_is_invalid(raw):
    with pytest.raises(FormatError, match="shortest form") as info:
        ByteReader(bytes.fromhex(raw), base_offset=7).varint("v")
    assert info.value.offset == 7


def test_varint_longer_than_ten_bytes_is_invalid():
    with pytest.raises(FormatError, match="longer than 10"):
        ByteReader(b"\x80" * 10 + b"\x01").varint("v")


def test_varint_of_two_to_the_64_is_invalid():
    with pytest.raises(FormatError, match="2\\*\\*64"):
        ByteReader(b"\x80" * 9 + b"\x02").varint("v")


def test_varint_cut_short_is_invalid():
    with pytest.raises(FormatError, match="truncated"):
        ByteReader(b"\x80\x80").varint("v")


def test_varint_above_the_field_limit_is_invalid():
    with pytest.raises(FormatError, match="exceeds the limit 10"):
        ByteReader(encode_varint(11)).varint("v", maximum=10)


def test_encode_varint_refuses_values_outside_u64():
    for bad in (-1, 1 << 64):
        with pytest.raises(FormatError):
            encode_varint(bad)


@pytest.mark.parametrize(("signed", "unsigned"), [(0, 0), (-1, 1), (1, 2), (-2, 3), (2, 4),
                                                  ((1 << 63) - 1, (1 << 64) - 2),
                                                  (-(1 << 63), (1 << 64) - 1)])
def test_zigzag_maps_as_the_spec_says(signed, unsigned):
    assert zigzag_encode(signed) == unsigned
    assert zigzag_decode(unsigned) == signed


@given(st.integers(-(1 << 63), (1 << 63) - 1))
def test_signed_varint_round_trips(value):
    writer = ByteWriter()
    writer.svarint(value)
    assert ByteReader(writer.getvalue()).svarint("v") == value


def test_crc32_is_iso_hdlc():
    assert crc32(b"123456789") == 0xCBF43926
    assert crc32(b"6789", crc32(b"12345")) == 0xCBF43926


def test_fixed_numbers_are_little_endian():
    writer = ByteWriter()
    writer.fixed("u16", 0x0102)
    writer.fixed("i32", -2)
    writer.fixed("f32", 1.5)
    assert writer.getvalue() == bytes.fromhex("0201" "feffffff" "0000c03f")
    reader = ByteReader(writer.getvalue())
    assert (reader.fixed("u16", "a"), reader.fixed("i32", "b"), reader.fixed("f32", "c")) == (
        0x0102, -2, 1.5)


def test_fixed_number_past_the_end_is_invalid_and_names_chunk_and_offset():
    with pytest.raises(FormatError) as info:
        ByteReader(b"\x01\x02", base_offset=100, chunk="Test").fixed("u32", "count")
    assert (info.value.chunk, info.value.offset) == ("Test", 102)


def test_byte_string_round_trips():
    writer = ByteWriter()
    writer.byte_string(b"hello")
    writer.byte_string(b"")
    reader = ByteReader(writer.getvalue())
    assert (reader.byte_string("a"), reader.byte_string("b")) == (b"hello", b"")


def test_byte_string_longer_than_the_rest_is_invalid_before_copying():
    data = encode_varint(1 << 40) + b"abc"
    with pytest.raises(FormatError, match="declares") as info:
        ByteReader(data, base_offset=5).byte_string("name")
    assert info.value.offset == 5


def test_array_round_trips_little_endian():
    values = np.array([1, -2, 300], dtype=np.int32)
    writer = ByteWriter()
    writer.array(values, "i4")
    assert writer.getvalue() == values.astype("<i4").tobytes()
    out = ByteReader(writer.getvalue()).array(3, "i4", "values")
    np.testing.assert_array_equal(out, values)


def test_array_count_beyond_the_bytes_is_invalid_before_allocating():
    with pytest.raises(FormatError, match="truncated"):
        ByteReader(b"\x00" * 8).array(1 << 60, "f4", "values")


def test_expect_end_rejects_trailing_bytes():
    reader = ByteReader(b"\x01\x02", chunk="Test")
    reader.raw(1, "a")
    with pytest.raises(FormatError, match="unexpected bytes"):
        reader.expect_end("the payload")
