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
from torch.nn import functional

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
        by_attribute: (3,) summed bits over all anchors of each of :data:`ATTRIBUTES`.
        parameters: number of coded values the bits are spread over (masked offsets count 0).
    """

    by_attribute: torch.Tensor
    parameters: torch.Tensor

    @property
    def bits(self) -> dict[str, torch.Tensor]:
        """Attribute name -> its summed bits (scalar tensor)."""
        return dict(zip(ATTRIBUTES, self.by_attribute.unbind()))

    @property
    def total(self) -> torch.Tensor:
        """Summed bits of every attribute."""
        return self.by_attribute.sum()

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

    The hyperprior's output is [mean of every coded column | log sigma of every column],
    columns in :data:`ATTRIBUTES` order (F features, 3K offsets, 6 scaling: W in all). The
    CARM's G - 1 networks (one per feature group g >= 1: Linear(start_g, hidden // 2), ReLU,
    Linear(hidden // 2, 2 width_g)) are held as one masked network over all F features whose
    output adds to that row, so a step runs two matrix products for them instead of two per
    group: block g of the first layer sees only the features before group g, and its outputs
    reach only group g's columns (the masks keep the other weights at zero and without
    gradient). Training on a GPU is bound by how many operators a step launches.

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
        width = sum(self.widths.values())
        in_width = 6 * EMBEDDING_OCTAVES
        self.hyper = nn.Sequential(nn.Linear(in_width, hidden, device=device), nn.ReLU(),
                                   nn.Linear(hidden, hidden, device=device), nn.ReLU(),
                                   nn.Linear(hidden, 2 * width, device=device))
        self.bounds = group_bounds(feat_dim, max(1, min(groups, feat_dim)))
        # Drawn as separate per-group layers (the initial values of a network per group),
        # then laid out as blocks of the masked network.
        nets = [(nn.Linear(start, hidden // 2, device=device),
                 nn.Linear(hidden // 2, 2 * (end - start), device=device))
                for start, end in self.bounds[1:]]
        blocks, half = len(nets), hidden // 2
        first = torch.zeros(blocks * half, feat_dim, device=device)
        first_bias = torch.zeros(blocks * half, device=device)
        second = torch.zeros(2 * width, blocks * half, device=device)
        second_bias = torch.zeros(2 * width, device=device)
        with torch.no_grad():
            for g, ((start, end), (inner, outer)) in enumerate(zip(self.bounds[1:], nets)):
                rows, group = slice(g * half, (g + 1) * half), end - start
                first[rows, :start] = inner.weight
                first_bias[rows] = inner.bias
                for part, at in ((slice(0, group), start), (slice(group, 2 * group),
                                                            width + start)):
                    second[at:at + group, rows] = outer.weight[part]
                    second_bias[at:at + group] = outer.bias[part]
        self.carm_first = nn.Parameter(first)
        self.carm_first_bias = nn.Parameter(first_bias)
        self.carm_second = nn.Parameter(second)
        self.carm_second_bias = nn.Parameter(second_bias)
        second_mask = _block_mask(second, self.bounds, half, width)
        self.register_buffer("carm_first_mask", _first_mask(first, self.bounds, half),
                             persistent=False)
        self.register_buffer("carm_second_mask", second_mask, persistent=False)
        self.register_buffer("carm_second_bias_mask", second_mask.sum(dim=1).clamp(max=1.0),
                             persistent=False)

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

    def entropy_parameters(self, cells: torch.Tensor, features: torch.Tensor
                           ) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean, log sigma), each (M, W) over the coded columns (class notes): the
        hyperprior's prediction from ``cells`` ((M, 3) int64) refined by the CARM over the
        (noisy) ``features`` (M, F)."""
        params = self.hyper(self._embedding(cells).to(features.device, features.dtype))
        if len(self.bounds) > 1:
            hidden = functional.relu(functional.linear(
                features, self.carm_first * self.carm_first_mask, self.carm_first_bias))
            params = params + functional.linear(
                hidden, self.carm_second * self.carm_second_mask,
                self.carm_second_bias * self.carm_second_bias_mask)
        mean, log_sigma = params.unflatten(1, (2, -1)).unbind(1)
        return mean, log_sigma

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
        mean, log_sigma = self.entropy_parameters(cells, features)
        values = torch.cat([noisy[name].reshape(m, self.widths[name]) for name in ATTRIBUTES],
                           dim=1)
        step, selector = self._column_constants(features)
        per_value = gaussian_rate_bits(values, mean, torch.exp(log_sigma) * step, step)
        # Offsets of masked slots cost nothing: every column weighted (1 for features and
        # scaling, the slot's mask for its three offsets), summed per column, then per
        # attribute by the 0/1 selector (W, 3).
        ones = self._ones(features, m)
        weights = torch.cat([ones[:, :self.widths["features"]],
                             mask[:, :, None].expand(-1, -1, 3).reshape(m, -1),
                             ones[:, self.widths["features"]:]], dim=1)
        bits = (per_value * weights).sum(dim=0) @ selector
        # The count is a normaliser, not a target: a gradient through the straight-through
        # mask here would push cheap slots on.
        coded = (m * (self.widths["features"] + self.widths["scaling"])
                 + 3 * mask.detach().sum())
        return RateEstimate(bits, coded)

    def _ones(self, like: torch.Tensor, m: int) -> torch.Tensor:
        """(m, F + 6) ones on ``like``'s device and dtype (made once per shape)."""
        cached = getattr(self, "_ones_cached", None)
        width = self.widths["features"] + self.widths["scaling"]
        if (cached is None or cached.shape != (m, width) or cached.device != like.device
                or cached.dtype != like.dtype):
            cached = torch.ones((m, width), dtype=like.dtype, device=like.device)
            self._ones_cached = cached
        return cached

    def _column_constants(self, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(1, W) quantization step of every coded column and the (W, 3) 0/1 matrix that
        sums columns per attribute, on ``like``'s device and dtype (made once per device
        and dtype)."""
        cached = getattr(self, "_columns_cached", None)
        if cached is None or cached[0].device != like.device or cached[0].dtype != like.dtype:
            step = torch.cat([torch.full((self.widths[name],), self.steps[name],
                                         dtype=like.dtype, device=like.device)
                              for name in ATTRIBUTES])[None, :]
            selector = torch.block_diag(*[torch.ones((self.widths[name], 1), dtype=like.dtype,
                                                     device=like.device)
                                          for name in ATTRIBUTES])
            cached = (step, selector)
            self._columns_cached = cached
        return cached


def _first_mask(first: torch.Tensor, bounds: list[tuple[int, int]], half: int
                ) -> torch.Tensor:
    """1 where the masked CARM's first layer may have weights: block g (rows g*half ..) sees
    the features before group g + 1."""
    mask = torch.zeros_like(first)
    for g, (start, _end) in enumerate(bounds[1:]):
        mask[g * half:(g + 1) * half, :start] = 1.0
    return mask


def _block_mask(second: torch.Tensor, bounds: list[tuple[int, int]], half: int, width: int
                ) -> torch.Tensor:
    """1 where the masked CARM's second layer may have weights: group g's mean and log-sigma
    rows (columns start..end of each half of the output) see only hidden block g."""
    mask = torch.zeros_like(second)
    for g, (start, end) in enumerate(bounds[1:]):
        for at in (start, width + start):
            mask[at:at + end - start, g * half:(g + 1) * half] = 1.0
    return mask
