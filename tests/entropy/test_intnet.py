"""Integer network: exact float64 == int64 inference, ranges and the exactness bound, bytes."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgs_codec.entropy.intnet import IntLayer, IntMLP, positional_embedding
from csgs_codec.entropy.intnet_bytes import intnet_from_bytes, intnet_to_bytes
from csgs_codec.entropy.tables import sine_table
from csgs_codec.errors import FormatError, InputError, ModelError
from tests.entropy._intnet_cases import random_network, random_positions


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 6), st.integers(1, 4), st.integers(2, 16),
       st.integers(1, 20))
def test_float64_and_int64_paths_give_identical_outputs(seed, freqs, depth, wbits, abits):
    net = random_network(seed, num_freqs=freqs, width=24, depth=depth, weight_bits=wbits,
                         act_bits=abits)
    x = random_positions(300, seed)
    assert np.array_equal(net.forward(x, "float64"), net.forward(x, "int64"))


@pytest.mark.parametrize("rows", [4095, 4096, 9001])
def test_half_of_the_rows_on_a_pool_gives_the_same_outputs(rows):
    """Blocks are 2,048 rows here: 4,095 rows run in one thread, 4,096 and 9,001 split."""
    from concurrent.futures import ThreadPoolExecutor

    class CountingPool(ThreadPoolExecutor):
        submitted = 0

        def submit(self, *args, **kwargs):
            self.submitted += 1
            return super().submit(*args, **kwargs)

    net = random_network(3, num_freqs=4, width=32, depth=3)
    x = random_positions(rows, 5)
    with CountingPool(1) as pool:
        for path in ("float64", "int64"):
            assert np.array_equal(net.forward(x, path, pool=pool), net.forward(x, path))
    assert pool.submitted == (0 if rows < 4096 else 2)


W23 = (1 << 23) - 1
A30 = (1 << 30) - 1


def _bound_network(extra: int) -> IntMLP:
    """Layer 2 worst case = W23 * A30 + bias = 2^53 + extra; layer 1 saturates at x = 0."""
    first = IntLayer(np.array([[0, W23, 0, 0, 0, 0]]), [0], 0, 24)
    second = IntLayer(np.array([[W23]]), [(1 << 53) - W23 * A30 + extra], 0, 24)
    return IntMLP(16, 1, 30, (first, second), [-(1 << 53)], [1 << 53])


def test_paths_agree_at_the_exactness_bound():
    net = _bound_network(0)
    assert net.worst_case_sums()[1] == 1 << 53
    x = np.array([[0, 0, 0], [100, 3, 9], [16384, 0, 0], [40000, 1, 1]])
    out = net.forward(x, "float64")
    assert out[0, 0] == 1 << 53
    assert np.array_equal(out, net.forward(x, "int64"))


def test_network_that_could_exceed_2_pow_53_is_refused():
    with pytest.raises(ModelError, match="2\\^53"):
        _bound_network(1)


def test_rounding_shift_rounds_half_up_and_relu_clamps():
    # Single hidden unit reading feature 1 (cos of axis 0): T[256] = 2^14 at x = 0.
    hidden = IntLayer(np.eye(2, 6, k=1, dtype=np.int64), [1, 0], 15, 8)
    last = IntLayer(np.array([[1, 0], [0, 1], [-1, 0]]), [0, 0, 0], 0, 8)
    net = IntMLP(16, 1, 3, (hidden, last), [-100, -100, -100], [100, 100, 100])
    # (2^14 + 1 + 2^14) >> 15 = 1; (0 + 0 + 2^14) >> 15 = 0; second output clamps at 0..7.
    out = net.forward(np.array([[0, 0, 0]]), "int64")
    assert out.tolist() == [[1, 0, -1]]


def test_outputs_are_clamped_to_their_index_ranges():
    net = random_network(4)
    out = net.forward(random_positions(2000))
    assert out[:, 1].min() >= 0 and out[:, 1].max() <= 63
    assert out[:, 2].min() >= 0 and out[:, 2].max() <= 175


def test_embedding_reads_the_sine_table_at_the_spec_phase():
    x = np.array([[16384, 0, 65535]])
    emb = positional_embedding(x, 16, 2)
    t = sine_table()
    # level 0: i = (x << 10) >> 16; level 1: i = (x << 11) >> 16 (mod 1024).
    for level in range(2):
        for d in range(3):
            i = ((int(x[0, d]) << (level + 10)) >> 16) % 1024
            assert emb[0, 6 * level + 2 * d] == t[i]
            assert emb[0, 6 * level + 2 * d + 1] == t[(i + 256) % 1024]


def test_positions_outside_the_grid_are_input_errors():
    net = random_network(0, pos_bits=10)
    with pytest.raises(InputError):
        net.forward(np.array([[1024, 0, 0]]))
    with pytest.raises(InputError):
        net.forward(np.array([[0.5, 0, 0]]))


def test_network_bytes_round_trip():
    net = random_network(2, weight_bits=12)
    data = intnet_to_bytes(net)
    back = intnet_from_bytes(data)
    assert intnet_to_bytes(back) == data
    x = random_positions(100)
    assert np.array_equal(back.forward(x), net.forward(x))


def test_pickled_network_gives_identical_outputs():
    net = random_network(3)
    x = random_positions(1000)
    assert np.array_equal(pickle.loads(pickle.dumps(net)).forward(x), net.forward(x))


def test_every_truncation_of_a_network_payload_is_a_format_error():
    data = intnet_to_bytes(random_network(5, num_freqs=1, width=8))
    for cut in range(len(data)):
        with pytest.raises(FormatError):
            intnet_from_bytes(data[:cut])
    with pytest.raises(FormatError):
        intnet_from_bytes(data + b"\x00")


def test_huge_declared_width_fails_before_allocating():
    data = bytes([1, 16, 1, 8, 1]) + b"\x80\x20" + bytes([8, 0])  # out_width 4096, no weights
    with pytest.raises(FormatError, match="truncated"):
        intnet_from_bytes(data)


@pytest.mark.parametrize("pos_bits,num_freqs", [(4, 8), (10, 3), (32, 16), (1, 1)])
def test_embedding_matches_the_spec_formula_for_every_shift_direction(pos_bits, num_freqs):
    rng = np.random.default_rng(pos_bits)
    x = rng.integers(0, 1 << pos_bits, (20, 3), dtype=np.int64)
    x[0] = (1 << pos_bits) - 1
    emb = positional_embedding(x, pos_bits, num_freqs)
    t = sine_table().tolist()
    for n, row in enumerate(x.tolist()):
        for level in range(num_freqs):
            for d in range(3):
                i = ((row[d] << (level + 10)) >> pos_bits) % 1024
                assert emb[n, 6 * level + 2 * d] == t[i]
                assert emb[n, 6 * level + 2 * d + 1] == t[(i + 256) % 1024]


@pytest.mark.parametrize("field", ["bias", "lo"])
def test_most_negative_int64_fields_are_refused(field):
    layer = IntLayer(np.ones((1, 6)), [-(2**63) if field == "bias" else 0], 0, 8)
    lo = [-(2**63) if field == "lo" else 0]
    with pytest.raises(ModelError):
        IntMLP(16, 1, 8, (layer,), lo, [1])
