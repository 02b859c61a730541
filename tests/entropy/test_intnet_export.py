"""Torch export to the integer network: fidelity, shape checks, overflow refusal."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import ModelError
from csgs_codec.model.intnet_export import export_mlp, float_embedding
from tests.entropy._intnet_cases import random_positions


def _mlp(seed: int = 0, freqs: int = 4) -> torch.nn.Sequential:
    torch.manual_seed(seed)
    return torch.nn.Sequential(torch.nn.Linear(6 * freqs, 64), torch.nn.ReLU(),
                               torch.nn.Linear(64, 64), torch.nn.ReLU(),
                               torch.nn.Linear(64, 3))


def test_exported_network_tracks_the_float_network():
    mlp = _mlp()
    x = random_positions(4000)
    net = export_mlp(mlp, pos_bits=16, num_freqs=4, calibration_positions=x,
                     out_lo=[-(1 << 30)] * 3, out_hi=[1 << 30] * 3, output_frac_bits=8)
    with torch.no_grad():
        ref = mlp(float_embedding(x, 16, 4)).double().numpy() * 256
    assert np.abs(net.forward(x) - ref).max() < 2.0
    assert np.array_equal(net.forward(x, "float64"), net.forward(x, "int64"))


def test_export_refuses_a_network_that_could_overflow():
    with pytest.raises(ModelError, match="export refused|does not fit"):
        export_mlp(_mlp(), pos_bits=16, num_freqs=4,
                   calibration_positions=random_positions(500),
                   out_lo=[0] * 3, out_hi=[1] * 3, weight_bits=24, act_bits=30,
                   output_frac_bits=0)


def test_export_refuses_wide_layers_over_the_bound():
    torch.manual_seed(1)
    mlp = torch.nn.Sequential(torch.nn.Linear(6, 4096), torch.nn.ReLU(),
                              torch.nn.Linear(4096, 1))
    with torch.no_grad():
        mlp[2].bias.zero_()
    with pytest.raises(ModelError, match="2\\^53"):
        export_mlp(mlp, pos_bits=16, num_freqs=1, calibration_positions=random_positions(200),
                   out_lo=[0], out_hi=[1], weight_bits=24, act_bits=28,
                   output_frac_bits=0)


def test_export_refuses_other_architectures():
    mlp = torch.nn.Sequential(torch.nn.Linear(24, 8), torch.nn.Tanh(), torch.nn.Linear(8, 3))
    with pytest.raises(ModelError, match="Sequential of Linear"):
        export_mlp(mlp, pos_bits=16, num_freqs=4, calibration_positions=random_positions(10),
                   out_lo=[0] * 3, out_hi=[1] * 3)


def test_export_refuses_a_first_layer_of_the_wrong_width():
    with pytest.raises(ModelError, match="embedding"):
        export_mlp(_mlp(freqs=4), pos_bits=16, num_freqs=3,
                   calibration_positions=random_positions(10), out_lo=[0] * 3,
                   out_hi=[1] * 3)
