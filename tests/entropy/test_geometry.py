"""Geometry coding: lossless round trips, canonical order, bad payloads, determinism."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgs_codec.entropy.geometry import canonical_order, decode_positions, encode_positions
from csgs_codec.entropy.morton import MAX_BITS, morton_decode, morton_encode
from csgs_codec.errors import FormatError, InputError
from tests.conftest import REPO, shared_path


def quantize_to_grid(positions: np.ndarray, bits: int) -> np.ndarray:
    """(N, 3) float positions -> (N, 3) int64 on a 2^bits grid over their bounding box."""
    p = positions.astype(np.float64)
    low, high = p.min(axis=0), p.max(axis=0)
    extent = np.where(high > low, high - low, 1.0)
    return np.round((p - low) / extent * ((1 << bits) - 1)).astype(np.int64)


def assert_round_trip(q: np.ndarray, bits: int) -> None:
    """Decoded points equal the input in canonical order (hence also as a multiset)."""
    decoded = decode_positions(encode_positions(q, bits))
    assert decoded.dtype == np.uint32
    assert decoded.shape == (q.shape[0], 3)
    np.testing.assert_array_equal(decoded, q[canonical_order(q, bits)])
    as_set = np.unique(q, axis=0, return_counts=True)
    got_set = np.unique(decoded.astype(np.int64), axis=0, return_counts=True)
    np.testing.assert_array_equal(as_set[0], got_set[0])
    np.testing.assert_array_equal(as_set[1], got_set[1])


@st.composite
def point_sets(draw):
    """(positions (N, 3) int64, bits): random, clustered, duplicated and extreme points."""
    bits = draw(st.integers(0, MAX_BITS))
    top = (1 << bits) - 1
    n = draw(st.integers(0, 300))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["uniform", "cluster", "equal", "extremes", "duplicates"]))
    if kind == "uniform":
        q = rng.integers(0, top + 1, (n, 3))
    elif kind == "cluster":
        center = rng.integers(0, top + 1, 3)
        q = np.clip(center + rng.integers(-3, 4, (n, 3)), 0, top)
    elif kind == "equal":
        q = np.repeat(rng.integers(0, top + 1, (1, 3)), n, axis=0)
    elif kind == "extremes":
        q = rng.choice(np.array([0, top]), (n, 3))
    else:
        base = rng.integers(0, top + 1, (max(1, n // 4), 3))
        q = base[rng.integers(0, base.shape[0], n)]
    return q.astype(np.int64), bits


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(point_sets())
def test_round_trip_is_exact_in_canonical_order(case):
    q, bits = case
    assert_round_trip(q, bits)


@pytest.mark.parametrize("bits", range(MAX_BITS + 1))
def test_every_bit_depth_round_trips(bits):
    rng = np.random.default_rng(bits)
    top = (1 << bits) - 1
    q = np.concatenate([rng.integers(0, top + 1, (200, 3)), [[0, 0, 0], [top, top, top]],
                        [[top, 0, top]] * 3])
    assert_round_trip(q, bits)


def test_empty_input_round_trips():
    assert_round_trip(np.zeros((0, 3), np.int64), 16)


def test_single_point_round_trips():
    assert_round_trip(np.array([[65535, 0, 12345]]), 16)


def test_all_equal_points_keep_their_count():
    q = np.full((1000, 3), 7, np.int64)
    few = encode_positions(q[:10], 16)
    assert len(encode_positions(q, 16)) <= len(few) + 2  # only the varint counts grow
    assert_round_trip(q, 16)


def test_input_dtypes_uint32_and_int64_give_the_same_payload():
    q = np.random.default_rng(3).integers(0, 1 << 16, (500, 3))
    assert encode_positions(q.astype(np.uint32), 16) == encode_positions(q, 16)


def test_canonical_order_is_increasing_morton_code():
    q = np.random.default_rng(4).integers(0, 1 << 10, (400, 3))
    codes = morton_encode(q[canonical_order(q, 10)])
    assert np.all(np.diff(codes.astype(np.float64)) >= 0)


def test_morton_code_interleaves_x_lowest():
    codes = morton_encode(np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 0, 0]]))
    assert codes.tolist() == [1, 2, 4, 8]
    full = (1 << MAX_BITS) - 1
    assert int(morton_encode(np.array([[full, full, full]]))[0]) == (1 << 63) - 1


def test_morton_decode_inverts_encode():
    q = np.random.default_rng(5).integers(0, 1 << MAX_BITS, (1000, 3))
    np.testing.assert_array_equal(morton_decode(morton_encode(q)), q)


@pytest.mark.parametrize("bad", [
    np.array([[1 << 16, 0, 0]]), np.array([[-1, 0, 0]]), np.zeros((3, 2), np.int64),
    np.zeros((2, 3), np.float32),
])
def test_encoder_rejects_positions_off_the_grid_or_badly_shaped(bad):
    with pytest.raises(InputError):
        encode_positions(bad, 16)


@pytest.mark.parametrize("bits", [-1, 22, 2.0])
def test_encoder_rejects_bits_out_of_range(bits):
    with pytest.raises(InputError):
        encode_positions(np.zeros((1, 3), np.int64), bits)


def _sample_payload() -> bytes:
    rng = np.random.default_rng(6)
    q = rng.integers(0, 1 << 12, (300, 3))
    return encode_positions(np.concatenate([q, q[:20]]), 12)


def test_every_truncation_raises_format_error():
    payload = _sample_payload()
    for cut in range(len(payload)):
        with pytest.raises(FormatError):
            decode_positions(payload[:cut])


def test_trailing_byte_raises_format_error():
    with pytest.raises(FormatError):
        decode_positions(_sample_payload() + b"\x00")


def test_unknown_version_raises_format_error_at_offset_0():
    payload = bytearray(_sample_payload())
    payload[0] = 2
    with pytest.raises(FormatError) as info:
        decode_positions(bytes(payload))
    assert info.value.offset == 0


def test_point_count_over_the_limit_is_refused_before_allocating():
    header = bytes([1, 16]) + b"\xff\xff\xff\xff\x7f"
    with pytest.raises(FormatError) as info:
        decode_positions(header + b"\x01\x00")
    assert info.value.offset == 2
    with pytest.raises(FormatError):
        decode_positions(encode_positions(np.zeros((10, 3), np.int64), 4), max_points=9)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_mutated_payloads_decode_or_raise_format_error(data):
    payload = bytearray(_sample_payload())
    for _ in range(data.draw(st.integers(1, 4))):
        at = data.draw(st.integers(0, len(payload) - 1))
        payload[at] = data.draw(st.integers(0, 255))
    try:
        out = decode_positions(bytes(payload))
    except FormatError:
        return
    assert out.dtype == np.uint32 and out.ndim == 2 and out.shape[1] == 3


_DECODE_SCRIPT = """
import hashlib, sys
from csgs_codec.entropy.geometry import decode_positions, encode_positions
import numpy as np
rng = np.random.default_rng(11)
q = rng.integers(0, 1 << 16, (20000, 3))
q = (q // 64) * 64 + rng.integers(0, 3, (20000, 3))
payload = encode_positions(q, 16)
print(hashlib.sha256(payload).hexdigest(), hashlib.sha256(decode_positions(payload)).hexdigest())
"""


def test_encode_and_decode_are_identical_under_thread_counts_1_and_2():
    results = []
    for threads in ("1", "2"):
        env = dict(os.environ, OMP_NUM_THREADS=threads, OPENBLAS_NUM_THREADS=threads,
                   MKL_NUM_THREADS=threads)
        out = subprocess.run([sys.executable, "-c", _DECODE_SCRIPT], env=env, cwd=REPO,
                             capture_output=True, text=True, check=True)
        results.append(out.stdout.split())
    assert results[0] == results[1]


def test_donut_positions_round_trip_at_16_bits():
    from csgs_codec.interchange.ply_io import read_ply

    scene = read_ply(shared_path("scenes", "donut.ply"))
    q = quantize_to_grid(scene.positions, 16)
    decoded = decode_positions(encode_positions(q, 16))
    np.testing.assert_array_equal(decoded, q[canonical_order(q, 16)])


def test_conformance_vectors_decode_as_recorded():
    from tests.conformance.geometry import check_vector

    folder = REPO / "spec" / "vectors" / "geometry"
    names = sorted(folder.glob("*.json"))
    assert len(names) >= 6
    for path in names:
        record = json.loads(path.read_text())
        assert check_vector(folder, record) == [], path.name
