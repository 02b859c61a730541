"""Whole-array varints of the escape side stream."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from csgs_codec.entropy.varints import decode_varints, encode_varints
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import encode_varint


@given(st.lists(st.integers(0, 2**64 - 1), max_size=50))
def test_varints_match_the_format_primitive_and_round_trip(values):
    data = encode_varints(np.array(values, dtype=np.uint64))
    assert data == b"".join(encode_varint(v) for v in values)
    assert decode_varints(data, len(values)).tolist() == values


@pytest.mark.parametrize("data,count", [
    (b"\x80", 1),                 # truncated
    (b"\x01\x02", 1),             # one varint too many
    (b"\x81\x00", 1),             # not shortest form
    (b"\xff" * 9 + b"\x02", 1),   # above 2^64 - 1
    (b"\xff" * 10 + b"\x01", 1),  # longer than 10 bytes
    (b"", 1),                     # missing
    (b"\x00", 0),                 # trailing
])
def test_malformed_varints_are_format_errors(data, count):
    with pytest.raises(FormatError):
        decode_varints(data, count)
