"""Geometry coder internals that the spec pins down: tables, blocks, frames, raw fields."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.entropy.geometry import decode_positions, encode_positions
from csgs_codec.entropy.geometry_bytes import field_bits, read_fields, read_varints, write_varints
from csgs_codec.entropy.geometry_models import TOTAL, block_bounds, normalized_frequencies
from csgs_codec.entropy.geometry_octree import FROM_FRAME, OCC_CONTEXT, TO_FRAME
from csgs_codec.errors import FormatError


def test_frequency_tables_sum_to_2_16_with_every_symbol_possible():
    rng = np.random.default_rng(0)
    counts = rng.integers(0, 10**6, (50, 255)) * (rng.random((50, 255)) < 0.1)
    counts[0] = 0
    freqs = normalized_frequencies(counts)
    assert np.all(freqs.sum(axis=1) == TOTAL)
    assert freqs.min() >= 1


def test_frequency_table_of_zero_counts_is_uniform_up_to_the_remainder():
    freqs = normalized_frequencies(np.zeros((1, 255), np.int64))[0]
    assert set(freqs[1:].tolist()) == {TOTAL // 255}
    assert freqs[0] == TOTAL - 254 * (TOTAL // 255)


def test_frequency_table_follows_the_integer_formula():
    counts = np.array([[5, 0, 3, 9]])
    free = TOTAL - 4
    expected = [1 + 5 * free // 17, 1, 1 + 3 * free // 17, 1 + 9 * free // 17]
    expected[3] += TOTAL - sum(expected)
    assert normalized_frequencies(counts)[0].tolist() == expected


@pytest.mark.parametrize("m, ends", [(0, [0]), (1024, [1024]), (1025, [512, 1025]),
                                     (5000, [625, 1250, 2500, 5000])])
def test_blocks_double_from_at_most_1024_symbols(m, ends):
    assert block_bounds(m) == ends


def test_node_frame_is_a_byte_permutation_and_inverts():
    for occ in (1, 3, 0x96, 255):
        for k in range(8):
            if occ >> k & 1:
                assert sorted(TO_FRAME[occ, k].tolist()) == list(range(256))
                np.testing.assert_array_equal(FROM_FRAME[occ, k][TO_FRAME[occ, k]],
                                              np.arange(256))


def test_node_frame_puts_the_node_at_child_0_and_its_siblings_first():
    # Parent with children 5 and 4 (x neighbours): node 5 mirrors to 0, its sibling to +x.
    occ = (1 << 5) | (1 << 4)
    assert TO_FRAME[occ, 5, 1 << 5] == 1
    assert TO_FRAME[occ, 5, 1 << 4] == 1 << 1
    assert OCC_CONTEXT[occ, 5] == 4 * 1 + 2 - 1
    # Sibling along z only: z becomes the first axis of the frame.
    occ = (1 << 0) | (1 << 4)
    assert TO_FRAME[occ, 0, 1 << 4] == 1 << 1


def test_raw_fields_round_trip_at_any_bit_offset_and_width():
    rng = np.random.default_rng(1)
    for width in (3, 30, 57, 60, 63):
        values = rng.integers(0, 1 << 62, 300).astype(np.uint64) & np.uint64((1 << width) - 1)
        raw = np.packbits(np.concatenate([np.ones(5, np.uint8), field_bits(values, width)]))
        np.testing.assert_array_equal(read_fields(raw, 5, 300, width), values)


def test_varint_lists_round_trip():
    values = np.array([0, 1, 127, 128, 300, 2**35, 2**63 - 1], np.uint64)
    data = write_varints(values)
    decoded, end = read_varints(data, 0, values.size, "test")
    np.testing.assert_array_equal(decoded, values)
    assert end == len(data)


def test_overlong_varint_is_rejected():
    with pytest.raises(FormatError):
        read_varints(b"\x80\x00", 0, 1, "test")


def test_nonzero_padding_bits_are_rejected():
    payload = bytearray(encode_positions(np.array([[1, 2, 3]]), 5))  # 15 raw bits, 1 padding
    decode_positions(bytes(payload))
    payload[-1] |= 1
    with pytest.raises(FormatError):
        decode_positions(bytes(payload))
