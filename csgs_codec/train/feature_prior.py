"""The simplest entropy model of the semantic feature, for the stage-3 rate term.

:class:`FactorizedGaussianPrior` gives every channel of s one learned Gaussian (mean, sigma)
shared by all anchors. It stands in wherever no position-conditioned hyperprior is plugged
into :func:`csgs_codec.train.semantic_stage.train_semantic_features`: any module whose
forward maps the features [G, D] to (mean, sigma) [G, D] fits the same slot (a hyperprior
conditioned on anchor positions holds the positions itself).
"""

from __future__ import annotations

import torch
from torch import nn


class FactorizedGaussianPrior(nn.Module):
    """One Gaussian per feature channel, learned: mean [D] and log-sigma [D].

    Args:
        dim: number of channels D.
        sigma: initial sigma of every channel, in quantization steps.
        device: where the parameters are made.
    """

    def __init__(self, dim: int, sigma: float = 2.0, *,
                 device: torch.device | str = "cpu") -> None:
        super().__init__()
        self.mean = nn.Parameter(torch.zeros(dim, device=device))
        self.log_sigma = nn.Parameter(torch.full((dim,), float(sigma), device=device).log())

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean, sigma), each [G, D] like ``features`` [G, D] (broadcast from the channels)."""
        mean = self.mean.to(features.dtype).expand_as(features)
        sigma = torch.exp(self.log_sigma).to(features.dtype).expand_as(features)
        return mean, sigma
