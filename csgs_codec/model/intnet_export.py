"""Export a trained torch MLP to the exact integer network of :mod:`csgs_codec.entropy.intnet`.

The torch network must read :func:`float_embedding` (the integer embedding divided by 2^14)
and be a ``Sequential`` of ``Linear`` layers separated by ``ReLU``. Each layer gets integer
weights round(W * 2^fw) with fw as large as ``weight_bits`` allows, integer biases at the
accumulator's scale, and a right shift to the next layer's activation scale, chosen from the
largest activation seen on calibration positions so it fits ``act_bits``. The export refuses
(ModelError) any network whose integer ranges could overflow the exact float64 range.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from csgs_codec.entropy.intnet import IntLayer, IntMLP, positional_embedding
from csgs_codec.entropy.tables import SINE_AMPLITUDE_BITS
from csgs_codec.errors import ModelError


def float_embedding(positions: np.ndarray, pos_bits: int, num_freqs: int,
                    device: torch.device | str = "cpu") -> torch.Tensor:
    """The embedding a torch hyperprior trains on: (N, 3) int -> (N, 6L) float32 in [-1, 1],
    on ``device``.

    It is the decoder's integer embedding divided by 2^14, so training sees exactly what the
    integer network will see.
    """
    emb = positional_embedding(positions, pos_bits, num_freqs)
    return torch.as_tensor(np.ldexp(emb.astype(np.float64), -SINE_AMPLITUDE_BITS),
                           device=device).float()


def _linear_layers(mlp: torch.nn.Module) -> list[torch.nn.Linear]:
    modules = list(mlp.children()) if isinstance(mlp, torch.nn.Sequential) else [mlp]
    linears = [m for m in modules if isinstance(m, torch.nn.Linear)]
    expected = []
    for i in range(len(linears)):
        expected.append(torch.nn.Linear)
        if i < len(linears) - 1:
            expected.append(torch.nn.ReLU)
    if not linears or [type(m) for m in modules] != expected:
        raise ModelError("export needs a Sequential of Linear layers separated by ReLU, got "
                         + ", ".join(type(m).__name__ for m in modules))
    return linears


def _exponent_to_fit(magnitude: float, limit: int) -> int:
    """Largest f with magnitude * 2^f <= limit (magnitude > 0)."""
    f = math.floor(math.log2(limit / magnitude))
    while magnitude * 2.0 ** f > limit:
        f -= 1
    return f


def quantize_layers(linears: list[torch.nn.Linear], x: torch.Tensor, frac_in: int,
                    weight_bits: tuple[int, ...], act_bits: int,
                    output_frac_bits: int = 0) -> list[IntLayer]:
    """Integer layers for ``linears`` reading ``x`` (float64 calibration inputs, which are
    integers times 2^-frac_in); outputs are round(float outputs * 2^output_frac_bits).
    ``weight_bits`` per layer; ModelError when a layer cannot be represented."""
    a_limit = (1 << act_bits) - 1
    layers = []
    with torch.no_grad():
        for i, linear in enumerate(linears):
            w_limit = (1 << (weight_bits[i] - 1)) - 1
            w = linear.weight.detach().double()
            b = (linear.bias.detach().double() if linear.bias is not None
                 else torch.zeros(w.shape[0], dtype=torch.float64, device=w.device))
            last = i == len(linears) - 1
            x = x @ w.T + b
            if last:
                frac_out = output_frac_bits
            else:
                x = torch.relu(x)
                peak = float(x.max()) if x.numel() else 0.0
                frac_out = _exponent_to_fit(peak, a_limit) if peak > 0 else act_bits
            w_peak = float(w.abs().max())
            frac_w = _exponent_to_fit(w_peak, w_limit) if w_peak > 0 else 0
            if not last and frac_out - frac_in > frac_w:
                # Small activations under large weights: the activation would need more
                # fraction bits than the weights can carry without a left shift, so it keeps
                # fewer (it then uses less of its range; it stays exact).
                frac_out = frac_w + frac_in
            frac_w = max(frac_w, frac_out - frac_in)
            if w_peak * 2.0 ** frac_w > w_limit + 0.5:
                raise ModelError(f"layer {i}: weights cannot reach the output scale within "
                                 f"{weight_bits[i]} bits", index=i)
            shift = frac_w + frac_in - frac_out
            w_int = torch.round(w * 2.0 ** frac_w).cpu().numpy().astype(np.int64)
            b_scaled = (b * 2.0 ** (frac_w + frac_in)).cpu().numpy()
            if not np.all(np.abs(b_scaled) < 2.0 ** 52):
                raise ModelError(f"layer {i}: bias does not fit 52 bits at its scale", index=i)
            layers.append(IntLayer(w_int, np.rint(b_scaled).astype(np.int64), int(shift),
                                   int(weight_bits[i])))
            frac_in = frac_out
    return layers


def export_mlp(mlp: torch.nn.Module, *, pos_bits: int, num_freqs: int,
               calibration_positions: np.ndarray, out_lo: np.ndarray, out_hi: np.ndarray,
               weight_bits: int = 12, act_bits: int = 14, output_frac_bits: int = 0) -> IntMLP:
    """Quantize ``mlp`` to an :class:`IntMLP`.

    Args:
        mlp: ``Sequential(Linear, ReLU, ..., Linear)`` taking 6L float embedding features.
        pos_bits, num_freqs: embedding parameters (positions in [0, 2^pos_bits)).
        calibration_positions: (M, 3) integer positions used to size the activation scales.
        out_lo, out_hi: (O,) inclusive integer range of each output index.
        weight_bits: signed bits per weight, 2..24.
        act_bits: hidden activation bits, 1..30.
        output_frac_bits: integer outputs are round(float output * 2^output_frac_bits).

    Returns:
        The integer network; raises ModelError when the torch network has another shape or
        the integer network could overflow (|accumulator| > 2^53 in the worst case).
    """
    linears = _linear_layers(mlp)
    if linears[0].in_features != 6 * num_freqs:
        raise ModelError(f"first layer takes {linears[0].in_features} inputs, the embedding "
                         f"has {6 * num_freqs}")
    if not 2 <= weight_bits <= 24 or not 1 <= act_bits <= 30:
        raise ModelError(f"weight_bits {weight_bits} / act_bits {act_bits} out of range")
    x = float_embedding(calibration_positions, pos_bits, num_freqs,
                        linears[0].weight.device).double()
    layers = quantize_layers(linears, x, SINE_AMPLITUDE_BITS, (weight_bits,) * len(linears),
                             act_bits, output_frac_bits)
    try:
        return IntMLP(pos_bits, num_freqs, act_bits, tuple(layers),
                      np.asarray(out_lo, dtype=np.int64), np.asarray(out_hi, dtype=np.int64))
    except ModelError as err:
        raise ModelError(f"export refused: {err.message}", index=err.index) from None
