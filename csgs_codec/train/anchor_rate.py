"""Stage 1's rate estimate: bits of the anchor attributes under an INR hyperprior and a CARM.

The model mirrors what the anchor codec fits at encode time (csgs_codec.model.anchor_hyperprior):
an MLP on the positional embedding of each anchor's grid cell (the codec's embedding,
:func:`csgs_codec.model.intnet_export.float_embedding`) predicts a mean and a sigma per channel
of the features f (F), offsets (3K) and scaling (6); for feature groups g >= 1 a small MLP over
the groups before it adds to their mean and log sigma (the channel-wise autoregressive model).
Training sees each value with uniform quantization noise of its attribute's step (the step the
encoder will use at the chosen quality), and its rate is the Gaussian mass of the step-wide bin
(:func:`csgs_codec.train.quantization.gaussian_rate_bits`). Offsets of masked slots cost nothing:
their bits are multiplied by the (straight-through) mask, so the rate pushes masks off too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from csgs_codec.entropy.anchor_attributes import group_bounds
from csgs_codec.model.intnet_export import float_embedding
from csgs_codec.train.quantization import gaussian_rate_bits

#: Octaves of the positional embedding the rate model sees.
EMBEDDING_OCTAVES = 6
#: Attribute types the rate covers, in output order.
ATTRIBUTES = ("features", "offsets", "scaling")


@dataclass
class RateEstimate:
    """Estimated bits of one step.

    Attributes:
        bits: attribute name -> scalar tensor, summed bits over all anchors.
        parameters: number of coded values the bits are spread over (masked offsets count 0).
    """

    bits: dict[str, torch.Tensor]
    parameters: torch.Tensor

    @property
    def total(self) -> torch.Tensor:
        """Summed bits of every attribute."""
        return sum(self.bits.values())

    @property
    def bits_per_parameter(self) -> torch.Tensor:
        """Total bits over the coded values (HAC's normalisation of the rate term)."""
        return self.total / self.parameters.clamp_min(1.0)


def cell_embedding(cells: torch.Tensor) -> torch.Tensor:
    """(M, 6L) float32 embedding of (M, 3) int64 cells, shifted to start at 0, on the cells'
    device."""
    c = cells.cpu().numpy()
    c = c - c.min(axis=0) if len(c) else c
    bits = max(int(c.max()).bit_length(), 1) if c.size else 1
    return float_embedding(c.astype(np.int64), bits, min(EMBEDDING_OCTAVES, max(bits - 1, 1)),
                           cells.device)


class AnchorRateModel(nn.Module):
    """The INR hyperprior and CARM of stage 1 (module notes).

    Args:
        feat_dim: F; n_offsets: K; groups: CARM feature groups (1: none).
        steps: attribute name -> quantization step, value units.
        hidden: width of the hidden layers.
        device: where the parameters are made.
    """

    def __init__(self, feat_dim: int, n_offsets: int, steps: dict[str, float], *,
                 groups: int = 5, hidden: int = 32,
                 device: torch.device | str = "cpu") -> None:
        super().__init__()
        self.widths = {"features": feat_dim, "offsets": 3 * n_offsets, "scaling": 6}
        self.steps = {name: float(steps[name]) for name in ATTRIBUTES}
        in_width = 6 * EMBEDDING_OCTAVES
        out = 2 * sum(self.widths.values())
        self.hyper = nn.Sequential(nn.Linear(in_width, hidden, device=device), nn.ReLU(),
                                   nn.Linear(hidden, hidden, device=device), nn.ReLU(),
                                   nn.Linear(hidden, out, device=device))
        self.bounds = group_bounds(feat_dim, max(1, min(groups, feat_dim)))
        self.carm = nn.ModuleList(
            nn.Sequential(nn.Linear(start, hidden // 2, device=device), nn.ReLU(),
                          nn.Linear(hidden // 2, 2 * (end - start), device=device))
            for start, end in self.bounds[1:])

    def _embedding(self, cells: torch.Tensor) -> torch.Tensor:
        cached = getattr(self, "_cached", None)
        if cached is not None and cached[0] is cells:  # same anchors as the last step
            return cached[1]
        emb = cell_embedding(cells)
        if emb.shape[1] < 6 * EMBEDDING_OCTAVES:  # tiny grids have fewer octaves
            emb = torch.cat([emb, emb.new_zeros(len(emb), 6 * EMBEDDING_OCTAVES
                                                 - emb.shape[1])], dim=1)
        self._cached = (cells, emb)
        return emb

    def estimate(self, cells: torch.Tensor, noisy: dict[str, torch.Tensor],
                 mask: torch.Tensor) -> RateEstimate:
        """Bits of the noisy attribute values.

        Args:
            cells: (M, 3) int64 anchor cells.
            noisy: "features" (M, F), "offsets" (M, K, 3), "scaling" (M, 6): values with
                quantization noise already added.
            mask: (M, K) float kept slots (straight-through).

        Returns:
            :class:`RateEstimate`.
        """
        m = cells.shape[0]
        features = noisy["features"]
        params = self.hyper(self._embedding(cells).to(features.device, features.dtype))
        # One bin-probability pass over every attribute's columns side by side: a third of
        # the kernels (and of the backward's) of one pass per attribute.
        values, means, log_sigmas, at = [], [], [], 0
        for name in ATTRIBUTES:
            width = self.widths[name]
            mean = params[:, at:at + width]
            log_sigma = params[:, at + width:at + 2 * width]
            at += 2 * width
            value = noisy[name].reshape(m, width)
            if name == "features":
                mean, log_sigma = self._carm(value, mean, log_sigma)
            values.append(value)
            means.append(mean)
            log_sigmas.append(log_sigma)
        step = self._step_row(features)
        per_value = gaussian_rate_bits(torch.cat(values, dim=1), torch.cat(means, dim=1),
                                       torch.exp(torch.cat(log_sigmas, dim=1)) * step, step)
        bits, at = {}, 0
        for name in ATTRIBUTES:
            width = self.widths[name]
            columns = per_value[:, at:at + width]
            if name == "offsets":
                columns = columns * mask.repeat_interleave(3, dim=1)
            bits[name] = columns.sum()
            at += width
        # The count is a normaliser, not a target: a gradient through the straight-through
        # mask here would push cheap slots on.
        coded = (m * (self.widths["features"] + self.widths["scaling"])
                 + 3 * mask.sum()).detach()
        return RateEstimate(bits, coded)

    def _step_row(self, like: torch.Tensor) -> torch.Tensor:
        """(1, F + 3K + 6) quantization step of every coded column, on ``like``'s device and
        dtype (made once per device and dtype)."""
        cached = getattr(self, "_steps_cached", None)
        if cached is None or cached.device != like.device or cached.dtype != like.dtype:
            cached = torch.cat([torch.full((self.widths[name],), self.steps[name],
                                           dtype=like.dtype, device=like.device)
                                for name in ATTRIBUTES])[None, :]
            self._steps_cached = cached
        return cached

    def _carm(self, values: torch.Tensor, mean: torch.Tensor, log_sigma: torch.Tensor
              ) -> tuple[torch.Tensor, torch.Tensor]:
        means, sigmas = [mean[:, :self.bounds[0][1]]], [log_sigma[:, :self.bounds[0][1]]]
        for net, (start, end) in zip(self.carm, self.bounds[1:]):
            delta = net(values[:, :start])
            width = end - start
            means.append(mean[:, start:end] + delta[:, :width])
            sigmas.append(log_sigma[:, start:end] + delta[:, width:])
        return torch.cat(means, dim=1), torch.cat(sigmas, dim=1)
