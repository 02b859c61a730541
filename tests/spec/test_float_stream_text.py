"""spec/FORMAT.md §12.8 as the reference decoder reads it, where the text was once unclear: a
predicted channel carries its bias even when it has no coefficients (channel 0); and the
``coding`` byte's reserved bits and combinations are refused where it sits."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.channel_coders import (
    PREDICTED_FLAG,
    SCORED_FLAG,
    TABLE_CONSTANT,
    TABLE_FROZEN,
    TABLE_HISTOGRAM,
)
from csgs_codec.attributes.float_stream import read_float_stream
from csgs_codec.entropy.residual import encode_symbols
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter


def test_a_predicted_channel_0_reads_a_bias_and_adds_floor_b_over_4096():
    out = ByteWriter()
    out.varint(2)          # count N
    out.fixed("u8", 1)     # channel_count
    out.fixed("u8", 0)     # frac_bits
    out.fixed("u8", TABLE_FROZEN | PREDICTED_FLAG)  # coding
    out.svarint(0)         # mean
    out.fixed("u8", 0)     # step_index: q = 1
    out.fixed("u8", 0)     # scale_index
    out.svarint(8192 + 5)  # bias B (no coefficients at channel 0): P = floor(B / 2^12) = 2
    out.byte_string(encode_symbols(np.array([0, 1]), np.zeros(2, np.int64)))
    reader = ByteReader(out.getvalue())
    values = read_float_stream(reader, 2, 1)
    reader.expect_end("the test stream")
    assert values[:, 0].tolist() == [2.0, 3.0]


@pytest.mark.parametrize("coding, message", [
    (TABLE_FROZEN | 0x04, "reserved bits"),
    (TABLE_FROZEN | 0x80, "reserved bits"),
    (TABLE_CONSTANT | PREDICTED_FLAG, "neither predicted nor scored"),
    (TABLE_HISTOGRAM | SCORED_FLAG, "frozen only"),
])
def test_bad_coding_bytes_are_refused_at_their_offset(coding, message):
    out = ByteWriter()
    out.varint(2)
    out.fixed("u8", 1)
    out.fixed("u8", 0)
    out.fixed("u8", coding)
    out.raw(bytes(16))
    with pytest.raises(FormatError, match=message) as info:
        read_float_stream(ByteReader(out.getvalue(), chunk="SHDC", base_offset=100), 2, 1)
    assert (info.value.chunk, info.value.offset) == ("SHDC", 103)
