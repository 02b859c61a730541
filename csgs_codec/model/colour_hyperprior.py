"""Fit the colour layer's INR hyperprior for a standard 3DGS scene (torch; encoder only).

The colour streams are quantized with the uniform steps of the quality preset, so this network
changes the rate only, never the reconstruction. For every Gaussian it reads the positional
embedding of the Gaussian's integer grid cell and predicts, for every channel of every colour
stream, a mean (units of 1/64 of a quantization step) and a scale-table index of the channel's
*base residual* b: the quantization index, or what is left of it after the channel-wise
prediction from the channels before it (csgs_codec/codec/float_stream.py). The coded symbol
is b - round(mean), with the frozen Gaussian table the scale index selects.

Training minimises the estimated bits, -log2 of the Gaussian mass of [b - 1/2, b + 1/2]
(b is already an integer: no noise relaxation), on one CPU thread with a fixed seed, so the
same scene and settings give the same network on this machine. The network is exported to
the exact integer network (:class:`~csgs_codec.entropy.intnet.IntMLP`); the codec then uses
only the integer outputs, which the decoder recomputes bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from csgs_codec.entropy.intnet import IntMLP
from csgs_codec.errors import ModelError
from csgs_codec.model.dense_export import export_position_mlp
from csgs_codec.model.fit_tools import (
    SCALE_MAX,
    Adam,
    clip_gradients,
    gaussian_bin_bits,
    mlp,
    num_freqs_for,
    scale_index_for_std,
    scaled_outputs,
)
from csgs_codec.model.intnet_export import float_embedding

#: Scale outputs are trained in units of 1/8 index (so Adam moves them gently).
INDEX_UNIT = 8.0
WEIGHT_BITS = (8, 8, 10)
GRAD_CLIP_NORM = 1000.0


@dataclass(frozen=True)
class ColourFitSettings:
    """Training settings of the colour hyperprior (defaults: about 10 s on one core)."""

    hidden: int = 32
    steps: int = 1500
    batch: int = 2048
    learning_rate: float = 5e-3
    seed: int = 0
    #: Activation scales are sized on at most this many Gaussians (every k-th).
    calibration_rows: int = 65536
    #: Batches are drawn from at most this many Gaussians (every k-th, in the spatially
    #: sorted order): 1,500 batches of 2,048 see each of them about 12 times, and the fit's
    #: memory stays flat for scenes of millions.
    training_rows: int = 1 << 18


def fit_colour_prior(cells: np.ndarray, pos_bits: int, residuals: np.ndarray,
                     settings: ColourFitSettings | None = None, *, mean_bits: int,
                     mean_limit: int, on_step=None) -> IntMLP:
    """Fit and export the colour hyperprior.

    Args:
        cells: (N, 3) integer grid cells in [0, 2^pos_bits), one per Gaussian.
        pos_bits: bits per cell coordinate.
        residuals: (N, T) int64 base residuals of the T modelled channels (in steps).
        settings: training settings.
        mean_bits, mean_limit: the format's mean outputs are in units of 2^-mean_bits steps
            and clamped to +-mean_limit (csgs_codec/codec/colour_prior.py).
        on_step: optional ``on_step(done, total)`` told of the training steps (every 50).

    Returns:
        An IntMLP with 2T outputs: T mean indices, then T scale-table indices in [0, 63].

    Raises:
        ModelError: the fit diverged or the network cannot be exported exactly.
    """
    settings = settings or ColourFitSettings()
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with torch.random.fork_rng(devices=[]):
            num_freqs = num_freqs_for(pos_bits)
            rows = _every_kth(len(cells), settings.training_rows)
            emb = float_embedding(cells[rows], pos_bits, num_freqs)
            net = _train(emb, residuals[rows].astype(np.float64), settings, on_step)
            rows = _every_kth(len(cells), settings.calibration_rows)
            t = residuals.shape[1]
            scales = np.array([2.0 ** mean_bits] * t + [INDEX_UNIT] * t)
            out_lo = np.array([-mean_limit] * t + [0] * t)
            out_hi = np.array([mean_limit] * t + [SCALE_MAX] * t)
            return export_position_mlp(scaled_outputs(net, scales), pos_bits=pos_bits,
                                       num_freqs=num_freqs, calibration_positions=cells[rows],
                                       out_lo=out_lo, out_hi=out_hi, weight_bits=WEIGHT_BITS)
    finally:
        torch.set_num_threads(threads)


def _every_kth(count: int, most: int) -> slice:
    """Evenly spaced rows, at most ``most`` of ``count``."""
    return slice(None, None, max(1, -(-count // most)))


def _train(emb: torch.Tensor, residuals: np.ndarray, s: ColourFitSettings,
           on_step=None) -> torch.nn.Module:
    """Train the float network; it starts as the factorized model (per-channel mean and
    scale in the output biases, small output weights)."""
    torch.manual_seed(s.seed)
    gen = torch.Generator().manual_seed(s.seed)
    n, t = residuals.shape
    net = mlp([emb.shape[1], s.hidden, s.hidden, 2 * t])
    with torch.no_grad():
        net[-1].weight.mul_(0.1)
        net[-1].bias[:t] = torch.from_numpy(np.median(residuals, axis=0))
        std = residuals.std(axis=0)
        net[-1].bias[t:] = torch.from_numpy(scale_index_for_std(std) / INDEX_UNIT)
    values = torch.from_numpy(residuals).float()
    optimizer = Adam(net.parameters(), lr=s.learning_rate)
    for step in range(s.steps):
        if step == s.steps * 3 // 4:
            optimizer.lr = s.learning_rate / 4
        rows = torch.randint(0, n, (min(s.batch, n),), generator=gen)
        optimizer.zero_grad()
        out = net(emb[rows])
        bits = gaussian_bin_bits(values[rows], out[:, :t], out[:, t:] * INDEX_UNIT, 1.0, 0.0)
        loss = bits.sum(dim=1).mean()
        if not torch.isfinite(loss):
            raise ModelError(f"the colour hyperprior fit diverged at step {step}")
        loss.backward()
        if not math.isfinite(clip_gradients(optimizer.params, GRAD_CLIP_NORM)):
            raise ModelError(f"the colour hyperprior fit diverged at step {step}")
        optimizer.step()
        if on_step is not None and ((step + 1) % 50 == 0 or step + 1 == s.steps):
            on_step(step + 1, s.steps)
    return net
