"""Histogram streams (spec/FORMAT.md §16.5): round trips, size estimate, vectors, bad input."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgs_codec.entropy.histogram import (
    MAX_SYMBOLS,
    decode_histogram,
    encode_histogram,
    histogram_cost,
)
from csgs_codec.errors import FormatError, InputError
from tests.conformance import VECTORS_DIR

DOCS = sorted((VECTORS_DIR / "histogram").glob("*.json"))


@pytest.mark.parametrize("values", [
    [], [0], [-3], [5] * 100, list(range(-50, 50)),
    [0] * 1000 + [1 << 62, -(1 << 62), 12345678],
])
def test_values_round_trip(values):
    data = encode_histogram(np.array(values, np.int64))
    assert decode_histogram(data, len(values)).tolist() == values


def test_a_range_wider_than_the_table_escapes_its_tails():
    rng = np.random.default_rng(1)
    values = np.concatenate([rng.integers(-3, 4, 20000), rng.integers(-10**9, 10**9, 5)])
    data = encode_histogram(values)
    assert np.array_equal(decode_histogram(data, values.size), values)
    assert len(data) < 20000  # the tails did not blow the table up to 2e9 entries


def test_the_cost_estimate_matches_the_coded_size():
    rng = np.random.default_rng(2)
    values = np.rint(np.concatenate([rng.normal(-8, 1, 30000), rng.normal(6, 2, 20000)]))
    bits = 8 * len(encode_histogram(values.astype(np.int64)))
    assert abs(histogram_cost(values.astype(np.int64)) - bits) <= 0.01 * bits + 64


def test_a_bimodal_channel_codes_near_its_entropy():
    rng = np.random.default_rng(3)
    values = np.rint(np.concatenate([rng.normal(-8, 1, 30000), rng.normal(6, 1, 30000)]))
    values = values.astype(np.int64)
    _, counts = np.unique(values, return_counts=True)
    entropy = -np.sum(counts * np.log2(counts / values.size))
    assert 8 * len(encode_histogram(values)) <= entropy * 1.01 + 400


def test_non_integer_or_oversized_values_are_refused():
    with pytest.raises(InputError):
        encode_histogram(np.array([0.5]))
    with pytest.raises(InputError):
        encode_histogram(np.array([(1 << 62) + 1], np.int64))


def test_the_table_never_exceeds_its_symbol_limit():
    values = np.arange(3 * MAX_SYMBOLS, dtype=np.int64)
    data = encode_histogram(values)
    assert np.array_equal(decode_histogram(data, values.size), values)


def test_vector_folder_holds_valid_and_invalid_streams():
    outcomes = {json.loads(p.read_text())["outcome"] for p in DOCS}
    assert outcomes == {"ok", "error"} and len(DOCS) >= 8


@pytest.mark.parametrize("path", DOCS, ids=lambda p: p.stem)
def test_histogram_vector_decodes_as_recorded(path):
    doc = json.loads(path.read_text())
    data = (path.parent / doc["file"]).read_bytes()
    assert hashlib.sha256(data).hexdigest() == doc["sha256"]
    if doc["outcome"] == "ok":
        assert decode_histogram(data, doc["count"]).tolist() == doc["values"]
        assert encode_histogram(np.array(doc["values"], np.int64)) == data
    else:
        with pytest.raises(FormatError) as info:
            decode_histogram(data, doc["count"])
        assert info.value.offset == doc["offset"]


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_mutated_streams_raise_only_format_errors(data):
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    values = rng.integers(-20, 20, data.draw(st.integers(1, 300)))
    payload = bytearray(encode_histogram(values))
    for _ in range(data.draw(st.integers(1, 4))):
        payload[data.draw(st.integers(0, len(payload) - 1))] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(payload)))
    try:
        out = decode_histogram(bytes(payload[:cut]), values.size)
    except FormatError:
        return
    assert out.shape == values.shape
