"""Integer networks over plain integer inputs: exact paths, ranges, bytes."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.entropy.intnet import IntLayer
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.errors import FormatError, InputError, ModelError
from csgs_codec.model.dense_export import export_dense_mlp


def random_dense(seed: int, in_width: int = 20, weight_bits: int = 12) -> IntDenseMLP:
    rng = np.random.default_rng(seed)
    top = 1 << (weight_bits - 1)
    layers = (IntLayer(rng.integers(-top, top, (16, in_width)), rng.integers(-999, 999, 16),
                       9, weight_bits),
              IntLayer(rng.integers(-top, top, (6, 16)), rng.integers(-999, 999, 6), 12,
                       weight_bits))
    return IntDenseMLP(in_width, 3, 14, 14, layers, np.full(6, -500), np.full(6, 500))


@pytest.mark.parametrize("seed", range(5))
def test_float64_and_int64_paths_agree(seed):
    net = random_dense(seed)
    x = np.random.default_rng(seed).integers(-(1 << 20), 1 << 20, (5000, 20))
    assert np.array_equal(net.forward(x, "float64"), net.forward(x, "int64"))


def test_payload_round_trips():
    net = random_dense(3)
    back = IntDenseMLP.from_bytes(net.to_bytes())
    x = np.random.default_rng(0).integers(-9999, 9999, (100, 20))
    assert np.array_equal(back.forward(x), net.forward(x))
    assert back.to_bytes() == net.to_bytes()


def test_a_network_that_could_leave_the_exact_range_is_refused():
    top = (1 << 23) - 1
    layer = IntLayer(np.full((4, 4096), top), np.zeros(4, np.int64), 0, 24)
    with pytest.raises(ModelError):
        IntDenseMLP(4096, 0, 30, 14, (layer,), np.zeros(4), np.zeros(4))


@pytest.mark.parametrize("cut", [1, 5, 40, -3])
def test_truncated_payload_is_a_format_error(cut):
    with pytest.raises(FormatError):
        IntDenseMLP.from_bytes(random_dense(1).to_bytes()[:cut])


def test_inputs_of_the_wrong_width_are_an_input_error():
    with pytest.raises(InputError):
        random_dense(0).forward(np.zeros((3, 7), np.int64))


def test_export_outputs_follow_the_torch_network():
    torch.manual_seed(0)
    mlp = torch.nn.Sequential(torch.nn.Linear(8, 16), torch.nn.ReLU(), torch.nn.Linear(16, 4))
    x = np.random.default_rng(0).integers(-4096, 4096, (2000, 8))
    net = export_dense_mlp(mlp, input_shift=6, input_bits=12, input_frac_bits=6,
                           calibration_inputs=x, out_lo=np.full(4, -1 << 20),
                           out_hi=np.full(4, 1 << 20), weight_bits=(12, 12))
    with torch.no_grad():
        expected = mlp(torch.from_numpy(np.ldexp((x >> 6).astype(np.float64), -6)).float())
    assert np.abs(net.forward(x) - expected.numpy()).max() <= 1.5


def test_tiny_hidden_activations_under_large_weights_still_export():
    """Regression (found by training): inputs near zero gave layer-0 activations so small that
    their scale needed more fraction bits than 8-bit weights can carry; export refused with
    "weights cannot reach the output scale". The hidden layer now keeps fewer fraction bits."""
    torch.manual_seed(1)
    mlp = torch.nn.Sequential(torch.nn.Linear(4, 8), torch.nn.ReLU(), torch.nn.Linear(8, 2))
    with torch.no_grad():
        mlp[0].weight.mul_(40.0)
        mlp[0].bias.fill_(1e-4)
    x = np.random.default_rng(1).integers(-2, 3, (500, 4))
    net = export_dense_mlp(mlp, input_shift=0, input_bits=12, input_frac_bits=12,
                           calibration_inputs=x, out_lo=np.full(2, -1 << 20),
                           out_hi=np.full(2, 1 << 20), weight_bits=(8, 10))
    with torch.no_grad():
        expected = mlp(torch.from_numpy(np.ldexp(x.astype(np.float64), -12)).float())
    assert np.abs(net.forward(x) - expected.numpy()).max() <= 1.5


@pytest.mark.parametrize("version", [1, 2])
def test_both_payload_versions_round_trip(version):
    net = random_dense(4)
    payload = net.to_bytes(version)
    assert payload[0] == version
    back = IntDenseMLP.from_bytes(payload)
    x = np.random.default_rng(1).integers(-9999, 9999, (100, 20))
    assert np.array_equal(back.forward(x, "int64"), net.forward(x, "int64"))
    assert all(np.array_equal(a.weights, b.weights) and np.array_equal(a.biases, b.biases)
               for a, b in zip(back.layers, net.layers))


def test_version_2_is_the_default_and_smaller_on_trained_like_weights():
    rng = np.random.default_rng(5)
    layers = (IntLayer(np.clip(np.rint(rng.normal(0, 20, (16, 20))), -128, 127).astype(int),
                       rng.integers(-999, 999, 16), 9, 8),
              IntLayer(np.clip(np.rint(rng.normal(0, 90, (6, 16))), -512, 511).astype(int),
                       rng.integers(-999, 999, 6), 12, 10))
    net = IntDenseMLP(20, 3, 14, 14, layers, np.full(6, -500), np.full(6, 500))
    assert net.to_bytes()[0] == 2
    assert len(net.to_bytes()) < 0.8 * len(net.to_bytes(1))


def test_a_dense_layer_beyond_the_coded_bound_falls_back_to_version_1(monkeypatch):
    from csgs_codec.entropy import residual

    monkeypatch.setattr(residual, "CODED_VALUE_SLACK", 0)  # stands in for > 65,536 zeros
    layers = (IntLayer(np.zeros((16, 20), np.int64), np.zeros(16, np.int64), 4, 8),
              IntLayer(np.zeros((2, 16), np.int64), np.zeros(2, np.int64), 4, 8))
    net = IntDenseMLP(20, 3, 14, 14, layers, np.zeros(2, np.int64), np.ones(2, np.int64))
    assert net.to_bytes()[0] == 1
    assert IntDenseMLP.from_bytes(net.to_bytes()).to_bytes() == net.to_bytes()


def test_unknown_dense_versions_are_refused():
    payload = random_dense(2).to_bytes()
    with pytest.raises(FormatError, match="version 3"):
        IntDenseMLP.from_bytes(bytes([3]) + payload[1:])
