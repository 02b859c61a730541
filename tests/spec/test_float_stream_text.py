"""spec/FORMAT.md §12.8 as the reference decoder reads it, where the text was once unclear: a
mode-2 channel carries its bias even when it has no coefficients (channel 0)."""

from __future__ import annotations

import numpy as np

from csgs_codec.codec.float_stream import read_float_stream
from csgs_codec.entropy.residual import encode_symbols
from csgs_codec.format.primitives import ByteReader, ByteWriter


def test_mode_2_at_channel_0_reads_a_bias_and_adds_floor_b_over_4096():
    out = ByteWriter()
    out.varint(2)          # count N
    out.fixed("u8", 1)     # channel_count
    out.fixed("u8", 0)     # frac_bits
    out.fixed("u8", 2)     # mode 2 (predicted)
    out.svarint(0)         # mean
    out.fixed("u8", 0)     # scale_index
    out.fixed("u8", 0)     # step_index: q = 1
    out.varint(0)          # coefficient_count m = c = 0
    out.svarint(8192 + 5)  # bias B: P = floor(B / 2^12) = 2
    out.byte_string(encode_symbols(np.array([0, 1]), np.zeros(2, np.int64)))
    reader = ByteReader(out.getvalue())
    values = read_float_stream(reader, 2, 1)
    reader.expect_end("the test stream")
    assert values[:, 0].tolist() == [2.0, 3.0]
