"""Export torch MLPs to exact integer networks with one weight width per layer.

:func:`export_position_mlp` makes an :class:`IntMLP` (positional embedding input, like
:func:`~csgs_codec.model.intnet_export.export_mlp`), :func:`export_dense_mlp` an
:class:`IntDenseMLP`, whose torch network reads ``x / 2^input_frac_bits`` with x the integer
input after the dense network's shift and clip. Both take a ``Sequential`` of ``Linear``
layers separated by ``ReLU``. Scales are chosen as ``export_mlp`` chooses them: the largest
weight scale that fits each layer's ``weight_bits``, activation scales from calibration
inputs.
"""

from __future__ import annotations

import numpy as np
import torch

from csgs_codec.entropy.intnet import IntMLP
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.entropy.tables import SINE_AMPLITUDE_BITS
from csgs_codec.errors import ModelError
from csgs_codec.model.intnet_export import _linear_layers, float_embedding, quantize_layers


def export_position_mlp(mlp: torch.nn.Module, *, pos_bits: int, num_freqs: int,
                        calibration_positions: np.ndarray, out_lo: np.ndarray,
                        out_hi: np.ndarray, weight_bits: tuple[int, ...],
                        act_bits: int = 14) -> IntMLP:
    """Like :func:`~csgs_codec.model.intnet_export.export_mlp` (output_frac_bits 0), with
    one weight width per layer (e.g. 8-bit hidden layers, a wider output layer)."""
    linears = _linear_layers(mlp)
    if len(weight_bits) != len(linears):
        raise ModelError(f"{len(weight_bits)} weight widths for {len(linears)} layers")
    x = float_embedding(calibration_positions, pos_bits, num_freqs,
                        linears[0].weight.device).double()
    layers = quantize_layers(linears, x, SINE_AMPLITUDE_BITS, weight_bits, act_bits)
    try:
        return IntMLP(pos_bits, num_freqs, act_bits, tuple(layers),
                      np.asarray(out_lo, dtype=np.int64), np.asarray(out_hi, dtype=np.int64))
    except ModelError as err:
        raise ModelError(f"export refused: {err.message}", index=err.index) from None


def export_dense_mlp(mlp: torch.nn.Module, *, input_shift: int, input_bits: int,
                     input_frac_bits: int, calibration_inputs: np.ndarray,
                     out_lo: np.ndarray, out_hi: np.ndarray, weight_bits: tuple[int, ...],
                     act_bits: int = 14) -> IntDenseMLP:
    """Quantize ``mlp`` to an :class:`IntDenseMLP` whose outputs are round(float outputs).

    Args:
        mlp: ``Sequential(Linear, ReLU, ..., Linear)`` taking D float inputs.
        input_shift, input_bits: the integer network's input shift and clip (see
            :class:`IntDenseMLP`).
        input_frac_bits: the torch network reads the shifted integer input times
            2^-input_frac_bits.
        calibration_inputs: (N, D) integer inputs (before the shift) sizing the activations.
        out_lo, out_hi: (O,) inclusive integer output ranges.
        weight_bits: signed bits per weight of each layer, 2..24; act_bits: hidden bits.

    Returns:
        The integer network; ModelError when the shape is not supported or the integer
        network would break the exactness bound.
    """
    linears = _linear_layers(mlp)
    if len(weight_bits) != len(linears):
        raise ModelError(f"{len(weight_bits)} weight widths for {len(linears)} layers")
    top = (1 << input_bits) - 1
    x_int = np.clip(np.asarray(calibration_inputs, dtype=np.int64) >> input_shift, -top, top)
    x = torch.as_tensor(np.ldexp(x_int.astype(np.float64), -input_frac_bits),
                        device=linears[0].weight.device)
    layers = quantize_layers(linears, x, input_frac_bits, weight_bits, act_bits)
    try:
        return IntDenseMLP(linears[0].in_features, input_shift, input_bits, act_bits,
                           tuple(layers), np.asarray(out_lo, dtype=np.int64),
                           np.asarray(out_hi, dtype=np.int64))
    except ModelError as err:
        raise ModelError(f"export refused: {err.message}", index=err.index) from None
