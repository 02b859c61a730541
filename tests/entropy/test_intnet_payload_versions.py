"""Network payload versions (spec/FORMAT.md §16.4.3): version 2 written, version 1 read, and
a decoder's allocation bounded by the payload."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.entropy import intnet_bytes as nb
from csgs_codec.entropy import residual
from csgs_codec.entropy.intnet import IntLayer, IntMLP
from csgs_codec.entropy.intnet_bytes import intnet_from_bytes, intnet_to_bytes
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteWriter

POSITIONS = np.array([[0, 0, 0], [65535, 1, 40000], [123, 4567, 32768]])


def _net(out_width: int = 3, bits: int = 10, seed: int = 1) -> IntMLP:
    rng = np.random.default_rng(seed)
    limit = 1 << (bits - 1)
    layers = (IntLayer(rng.integers(-127, 128, (8, 12)), rng.integers(-5000, 5000, 8), 10, 8),
              IntLayer(rng.integers(-limit, limit, (out_width, 8)),
                       rng.integers(-(2**40), 2**40, out_width), 9, bits))
    return IntMLP(16, 2, 12, layers, np.full(out_width, -(2**50)), np.full(out_width, 2**50))


def _equal(a: IntMLP, b: IntMLP) -> bool:
    return all(np.array_equal(x.weights, y.weights) and np.array_equal(x.biases, y.biases)
               and x.shift == y.shift and x.weight_bits == y.weight_bits
               for x, y in zip(a.layers, b.layers))


@pytest.mark.parametrize("version", [1, 2])
def test_both_versions_round_trip_the_same_network(version):
    net = _net()
    payload = nb.intnet_to_bytes(net, version)
    assert payload[0] == version
    decoded = intnet_from_bytes(payload)
    assert _equal(decoded, net)
    assert np.array_equal(decoded.forward(POSITIONS, path="int64"),
                          net.forward(POSITIONS, path="int64"))


def test_version_2_is_the_default_and_smaller_on_trained_like_weights():
    rng = np.random.default_rng(2)
    layers = (IntLayer(np.clip(np.rint(rng.normal(0, 30, (8, 12))), -128, 127).astype(int),
                       rng.integers(-5000, 5000, 8), 10, 8),
              IntLayer(np.clip(np.rint(rng.normal(0, 120, (40, 8))), -512, 511).astype(int),
                       rng.integers(-(2**20), 2**20, 40), 9, 10))
    net = IntMLP(16, 2, 12, layers, np.full(40, -(2**30)), np.full(40, 2**30))
    assert intnet_to_bytes(net)[0] == nb.INTNET_VERSION == 2
    assert len(intnet_to_bytes(net)) < 0.75 * len(nb.intnet_to_bytes(net, 1))


def test_a_near_constant_layer_beyond_the_bound_falls_back_to_version_1(monkeypatch):
    # stands in for a layer of more than 65,536 zeros
    monkeypatch.setattr(residual, "CODED_VALUE_SLACK", 0)
    layers = (IntLayer(np.zeros((16, 12), np.int64), np.zeros(16, np.int64), 4, 8),
              IntLayer(np.zeros((1, 16), np.int64), np.zeros(1, np.int64), 4, 8))
    net = IntMLP(16, 2, 12, layers, np.zeros(1, np.int64), np.ones(1, np.int64))
    assert intnet_to_bytes(net)[0] == 1
    assert _equal(intnet_from_bytes(intnet_to_bytes(net)), net)


def _header(out_width: int, bits: int = 8) -> ByteWriter:
    out = ByteWriter()
    for value in (2, 16, 2, 12, 1):  # version 2, pos_bits, L, act_bits, one layer
        out.fixed("u8", value)
    out.varint(out_width)
    out.fixed("u8", bits)
    out.fixed("u8", 4)
    return out


def test_a_layer_too_large_for_the_bytes_left_is_refused_before_decoding(monkeypatch):
    # 4096 x 12 weights with nothing left to hold them
    monkeypatch.setattr(residual, "CODED_VALUE_SLACK", 0)
    with pytest.raises(FormatError, match="weights exceed"):
        intnet_from_bytes(_header(4096).getvalue())


def test_weights_outside_their_bits_are_refused():
    from csgs_codec.entropy.residual import encode_symbols

    out = _header(1, bits=4)
    weights = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8, -1, -2, -3], np.int64)  # 8 needs 5 bits
    out.fixed("u8", 20)
    out.byte_string(encode_symbols(weights, np.full(12, 20, np.int64)))
    out.svarint(0)
    out.svarint(0)
    out.svarint(1)
    with pytest.raises(FormatError, match="outside 4 signed bits"):
        intnet_from_bytes(out.getvalue())


def test_a_bias_of_2_to_the_52_is_refused():
    from csgs_codec.entropy.residual import encode_symbols

    out = _header(1)
    out.fixed("u8", 20)
    out.byte_string(encode_symbols(np.zeros(12, np.int64), np.full(12, 20, np.int64)))
    out.svarint(2**52)
    out.svarint(0)
    out.svarint(1)
    with pytest.raises(FormatError, match="bias"):
        intnet_from_bytes(out.getvalue())


def test_unknown_versions_are_refused():
    payload = intnet_to_bytes(_net())
    with pytest.raises(FormatError, match="version 3"):
        intnet_from_bytes(bytes([3]) + payload[1:])
