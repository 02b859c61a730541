"""Residual coding: exact round trips (escapes included), reconstruction rule, bad streams."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from csgs_codec.entropy.residual import (
    STEP_COUNT,
    decode_residuals,
    decode_symbols,
    encode_residuals,
    encode_symbols,
    from_grid,
    quantize,
    reconstruct,
    reconstructed_values,
    step_index,
    step_size,
    to_grid,
)
from csgs_codec.entropy.varints import encode_varints
from csgs_codec.errors import FormatError, InputError

BIG = 2**53
values_st = st.integers(-BIG, BIG)


@st.composite
def channels(draw, max_size=60):
    n = draw(st.integers(0, max_size))
    kind = draw(st.sampled_from(["random", "equal", "outliers"]))
    if kind == "equal":
        values = [draw(values_st)] * n
    elif kind == "outliers":
        values = draw(st.lists(st.sampled_from([BIG, -BIG, BIG - 1, 0, 1, -1, 10**15]),
                               min_size=n, max_size=n))
    else:
        values = draw(st.lists(st.integers(-3000, 3000), min_size=n, max_size=n))
    mean = draw(st.lists(st.one_of(st.integers(-3000, 3000), values_st), min_size=n, max_size=n))
    scale = draw(st.lists(st.integers(0, 63), min_size=n, max_size=n))
    step = draw(st.lists(st.integers(0, STEP_COUNT - 1), min_size=n, max_size=n))
    return tuple(np.array(v, dtype=np.int64) for v in (values, mean, scale, step))


def _case(values, mean, scale, step):
    return tuple(np.array(v, dtype=np.int64) for v in (values, mean, scale, step))


@settings(max_examples=150, deadline=None)
@given(channels())
@example(_case([], [], [], []))
@example(_case([12345], [-7], [33], [100]))
@example(_case([BIG] * 9, [BIG] * 9, [0] * 9, [0] * 9))
@example(_case([BIG, -BIG, 0], [-BIG, BIG, 0], [0, 0, 63], [0, 0, 175]))
def test_residual_stream_round_trips_to_the_encoder_reconstruction(case):
    values, mean, scale, step = case
    data = encode_residuals(values, mean, scale, step)
    decoded = decode_residuals(data, mean, scale, step)
    assert np.array_equal(decoded, reconstructed_values(values, mean, step))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(-2**62, 2**62), st.integers(0, 63)), max_size=80))
def test_any_residual_up_to_2_pow_62_round_trips(pairs):
    r = np.array([p[0] for p in pairs], dtype=np.int64)
    s = np.array([p[1] for p in pairs], dtype=np.int64)
    assert np.array_equal(decode_symbols(encode_symbols(r, s), s), r)


def test_empty_stream_is_two_zero_bytes():
    empty = np.zeros(0, dtype=np.int64)
    assert encode_residuals(empty, empty, empty, empty) == b"\x00\x00"
    assert decode_residuals(b"\x00\x00", empty, empty, empty).size == 0


def test_step_size_follows_the_spec_formula():
    expected = [m if m < 16 else (8 + m % 8) << (m // 8 - 1) for m in range(1, STEP_COUNT + 1)]
    assert step_size(np.arange(STEP_COUNT)).tolist() == expected
    assert np.all(np.diff(expected) > 0)
    assert expected[:16] == list(range(1, 17)) and expected[16:18] == [18, 20]
    assert expected[-1] == 2**24


def test_quantization_rounds_half_up():
    mean = np.zeros(6, dtype=np.int64)
    step = np.full(6, 3, dtype=np.int64)  # q = 4
    values = np.array([2, -2, 6, -6, 1, -3])
    assert quantize(values, mean, step).tolist() == [1, 0, 2, -1, 0, -1]
    assert reconstruct(mean, [1, 0, 2, -1, 0, -1], step).tolist() == [4, 0, 8, -4, 0, -4]


def test_reconstruction_error_is_at_most_half_a_step():
    rng = np.random.default_rng(3)
    values = rng.integers(-10**9, 10**9, 5000)
    mean = rng.integers(-10**9, 10**9, 5000)
    step = rng.integers(0, STEP_COUNT, 5000)
    err = reconstructed_values(values, mean, step) - values
    q = step_size(step)
    assert np.all(2 * err <= q) and np.all(2 * err > -q)


def test_grid_conversion_is_exact_for_grid_values():
    ints = np.array([-(2**40), -3, 0, 5, 2**40])
    assert np.array_equal(to_grid(from_grid(ints, 12), 12), ints)


def test_large_residuals_use_the_escape_path_and_cost_more():
    scale = np.zeros(100, dtype=np.int64)
    small = encode_symbols(np.zeros(100, dtype=np.int64), scale)
    escaped = encode_symbols(np.full(100, 1000, dtype=np.int64), scale)
    assert len(escaped) > len(small) + 100


@pytest.mark.parametrize("bad", [
    dict(values=np.array([1.5])),
    dict(values=np.array([2**54])),
    dict(step=np.array([STEP_COUNT])),
    dict(scale=np.array([64])),
    dict(scale=np.array([-1])),
    dict(mean=np.array([1, 2])),
])
def test_bad_encoder_inputs_are_input_errors(bad):
    args = dict(values=np.array([1]), mean=np.array([0]), scale=np.array([0]),
                step=np.array([0]))
    args.update(bad)
    with pytest.raises(InputError):
        encode_residuals(args["values"], args["mean"], args["scale"], args["step"])


def test_every_truncation_and_byte_flip_is_a_format_error_or_decodes():
    rng = np.random.default_rng(5)
    n = 120
    values, mean = rng.integers(-10**6, 10**6, n), rng.integers(-10**6, 10**6, n)
    scale, step = rng.integers(0, 64, n), rng.integers(0, 30, n)
    data = encode_residuals(values, mean, scale, step)
    for cut in range(len(data)):
        with pytest.raises(FormatError):
            decode_residuals(data[:cut], mean, scale, step)
    for pos in range(len(data)):
        damaged = bytearray(data)
        damaged[pos] ^= 0x5A
        try:
            out = decode_residuals(bytes(damaged), mean, scale, step)
        except FormatError:
            continue
        assert out.shape == (n,)


def test_escaped_residual_beyond_2_pow_62_is_rejected():
    scale = np.zeros(1, dtype=np.int64)
    data = encode_symbols(np.array([2**62]), scale)
    assert np.array_equal(decode_symbols(data, scale), [2**62])
    head = data[:-9]  # the escape varint of 2^62 is its last 9 bytes
    bumped = head + encode_varints(np.array([2 * (2**62 - 2)], dtype=np.uint64))
    with pytest.raises(FormatError, match="2\\^62"):
        decode_symbols(bumped, scale)


def test_stream_with_another_count_than_the_caller_is_rejected():
    one = np.zeros(1, dtype=np.int64)
    data = encode_residuals(one, one, one, one)
    two = np.zeros(2, dtype=np.int64)
    with pytest.raises(FormatError, match="expects"):
        decode_residuals(data, two, two, two)


def test_step_index_inverts_step_size_and_picks_the_nearest_step():
    grid = step_size(np.arange(STEP_COUNT))
    assert np.array_equal(step_index(grid.astype(np.float64)), np.arange(STEP_COUNT))
    assert step_index(np.array([0.1, 16.9, 17.1, 1e12])).tolist() == [0, 15, 16, 175]
