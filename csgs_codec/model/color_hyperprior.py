"""Fit the color layer's INR hyperprior for a standard 3DGS scene (torch; encoder only).

The color streams are quantized with the uniform steps of the quality preset, so this network
changes the rate only, never the reconstruction. For every Gaussian it reads the positional
embedding of the Gaussian's integer grid cell and predicts, for every channel of every color
stream, a mean (units of 1/64 of a quantization step) and a scale-table index of the channel's
*base residual* b: the quantization index, or what is left of it after the channel-wise
prediction from the channels before it (csgs_codec/attributes/float_stream.py). The coded symbol
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
    GRAD_CLIP_NORM,
    INDEX_UNIT,
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
from csgs_codec.model.seeded_init import seeded_global_rng

#: Signed weight bits per layer of the exported network.
WEIGHT_BITS = (8, 8, 10)


@dataclass(frozen=True)
class ColorFitSettings:
    """Training settings of the color hyperprior (defaults: about 10 s on one core)."""

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


class ColorPriorFit:
    """A color hyperprior fit that can run in parts, with an export between them (the
    encoder looks at a short trial before paying for the whole fit). Training to step k in
    one call or in several gives the same network.

    Args:
        cells: (N, 3) integer grid cells in [0, 2^pos_bits), one per Gaussian.
        pos_bits: bits per cell coordinate.
        residuals: (N, T) int64 base residuals of the T modelled channels (in steps).
        settings: training settings.
        mean_bits, mean_limit: the format's mean outputs are in units of 2^-mean_bits steps
            and clamped to +-mean_limit (csgs_codec/chunks/color_prior.py).

    The exported network has 2T outputs: T mean indices, then T scale-table indices in
    [0, 63].
    """

    def __init__(self, cells: np.ndarray, pos_bits: int, residuals: np.ndarray,
                 settings: ColorFitSettings | None = None, *, mean_bits: int,
                 mean_limit: int) -> None:
        self.settings = s = settings or ColorFitSettings()
        self.cells, self.pos_bits = cells, pos_bits
        self.num_freqs = num_freqs_for(pos_bits)
        rows = _every_kth(len(cells), s.training_rows)
        self.emb = float_embedding(cells[rows], pos_bits, self.num_freqs)
        values = residuals[rows].astype(np.float64)
        self.t = residuals.shape[1]
        t = self.t
        self.scales = np.array([2.0 ** mean_bits] * t + [INDEX_UNIT] * t)
        self.out_lo = np.array([-mean_limit] * t + [0] * t)
        self.out_hi = np.array([mean_limit] * t + [SCALE_MAX] * t)
        device = self.emb.device
        with seeded_global_rng(s.seed):
            # It starts as the factorized model: per-channel mean and scale in the output
            # biases, small output weights.
            self.net = mlp([self.emb.shape[1], s.hidden, s.hidden, 2 * t], device=device)
            with torch.no_grad():
                self.net[-1].weight.mul_(0.1)
                self.net[-1].bias[:t] = torch.as_tensor(np.median(values, axis=0),
                                                        device=device)
                self.net[-1].bias[t:] = torch.as_tensor(
                    scale_index_for_std(values.std(axis=0)) / INDEX_UNIT, device=device)
        self.values = torch.as_tensor(values, device=device).float()
        self.gen = torch.Generator(device=device).manual_seed(s.seed)
        self.optimizer = Adam(self.net.parameters(), lr=s.learning_rate)
        self.steps_done = 0

    def train(self, until: int, on_step=None) -> None:
        """Train up to step ``until`` (at most ``settings.steps``), on one torch thread.

        Raises:
            ModelError: the loss or a gradient stopped being finite.
        """
        s = self.settings
        threads = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            n = self.values.shape[0]
            t = self.t
            for step in range(self.steps_done, min(until, s.steps)):
                if step == s.steps * 3 // 4:
                    self.optimizer.lr = s.learning_rate / 4
                rows = torch.randint(0, n, (min(s.batch, n),), generator=self.gen,
                                     device=self.values.device)
                self.optimizer.zero_grad()
                # index_select: the same rows as emb[rows], several times faster on the CPU
                out = self.net(torch.index_select(self.emb, 0, rows))
                bits = gaussian_bin_bits(torch.index_select(self.values, 0, rows),
                                         out[:, :t], out[:, t:] * INDEX_UNIT, 1.0, 0.0)
                loss = bits.sum(dim=1).mean()
                if not torch.isfinite(loss):
                    raise ModelError(f"the color hyperprior fit diverged at step {step}")
                loss.backward()
                if not math.isfinite(clip_gradients(self.optimizer.params, GRAD_CLIP_NORM)):
                    raise ModelError(f"the color hyperprior fit diverged at step {step}")
                self.optimizer.step()
                self.steps_done = step + 1
                if on_step is not None and (self.steps_done % 50 == 0
                                            or self.steps_done == s.steps):
                    on_step(self.steps_done, s.steps)
        finally:
            torch.set_num_threads(threads)

    def export(self) -> IntMLP:
        """The exact integer network of the fit so far.

        Raises:
            ModelError: it cannot be exported exactly.
        """
        rows = _every_kth(len(self.cells), self.settings.calibration_rows)
        return export_position_mlp(scaled_outputs(self.net, self.scales),
                                   pos_bits=self.pos_bits, num_freqs=self.num_freqs,
                                   calibration_positions=self.cells[rows], out_lo=self.out_lo,
                                   out_hi=self.out_hi, weight_bits=WEIGHT_BITS)


def _every_kth(count: int, most: int) -> slice:
    """Evenly spaced rows, at most ``most`` of ``count``."""
    return slice(None, None, max(1, -(-count // most)))
