"""Mutated and truncated PLY files: only InputError escapes, and memory stays bounded."""

from __future__ import annotations

import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import parse_ply_bytes
from tests.heap_peak import heap_peak
from tests.scene.ply_samples import make_ply, property_names, random_values

NAMES = property_names(9, extra=("sem_0",))
BINARY = make_ply(random_values(6, NAMES), NAMES)
ASCII = make_ply(random_values(6, NAMES), NAMES, fmt="ascii")
HEADER_WORDS = [b"ply", b"format", b"ascii", b"binary_big_endian", b"element", b"vertex",
                b"property", b"float", b"list", b"uchar", b"end_header", b"\n", b" ",
                b"99999999999", b"0", b"-1", b"f_rest_3", b"x", b"comment"]


def parse_bounded(data: bytes) -> None:
    """Parse ``data``; fail the test on anything but InputError or an over-large allocation."""
    try:
        with heap_peak() as peak, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            parse_ply_bytes(data, source="fuzz.ply")
    except InputError:
        pass
    assert peak.bytes <= 64 * len(data) + (1 << 20), \
        f"peak {peak.bytes} bytes for {len(data)} input bytes"


@st.composite
def mutated(draw, base: bytes):
    data = bytearray(base)
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.sampled_from(["flip", "byte", "insert", "delete", "word"]))
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "flip" and data:
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif kind == "byte" and data:
            data[pos] = draw(st.integers(0, 255))
        elif kind == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif kind == "delete" and data:
            del data[pos:pos + draw(st.integers(1, 16))]
        else:
            data[pos:pos] = draw(st.sampled_from(HEADER_WORDS))
    return bytes(data[: draw(st.integers(0, len(data)))])


FAST = settings(max_examples=300, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@FAST
@given(mutated(BINARY))
def test_mutated_binary_ply_only_raises_input_error(data):
    parse_bounded(data)


@FAST
@given(mutated(ASCII))
def test_mutated_ascii_ply_only_raises_input_error(data):
    parse_bounded(data)


@pytest.mark.parametrize("base", [BINARY, ASCII], ids=["binary", "ascii"])
def test_every_truncation_only_raises_input_error(base):
    for cut in range(len(base)):
        parse_bounded(base[:cut])


@pytest.mark.slow
@settings(max_examples=20000, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(st.one_of(mutated(BINARY), mutated(ASCII)))
def test_many_mutations_only_raise_input_error(data):
    parse_bounded(data)
