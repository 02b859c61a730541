"""Adam without ``torch.optim``: the semantic stages' optimiser.

``torch.optim.Optimizer.__init__`` imports ``torch._dynamo`` the first time it runs (1.2 s on
the project's CPU machine, about 6 s with CUDA on the H100 check, where it was most of the
cold semantic-stage test). These stages need only plain Adam, so it is written out here with
torch's update rule and defaults (betas 0.9, 0.999, eps 1e-8, no weight decay):

    m = b1 m + (1 - b1) g;  v = b2 v + (1 - b2) g^2
    p -= (lr / (1 - b1^t)) * m / (sqrt(v) / sqrt(1 - b2^t) + eps)
"""

from __future__ import annotations

import math

import torch


class PlainAdam:
    """Adam over a list of tensors that require gradients (updated in place)."""

    def __init__(self, params: list[torch.Tensor], lr: float, betas=(0.9, 0.999),
                 eps: float = 1e-8) -> None:
        self.params = list(params)
        self.lr, self.betas, self.eps = float(lr), betas, float(eps)
        self.step_count = 0
        self.first = [torch.zeros_like(p) for p in self.params]
        self.second = [torch.zeros_like(p) for p in self.params]

    def zero_grad(self) -> None:
        """Forget the parameters' gradients."""
        for p in self.params:
            p.grad = None

    @torch.no_grad()
    def step(self) -> None:
        """One update from the parameters' current gradients (those without one stay)."""
        self.step_count += 1
        b1, b2 = self.betas
        step_size = self.lr / (1.0 - b1 ** self.step_count)
        root_correction = math.sqrt(1.0 - b2 ** self.step_count)
        for p, m, v in zip(self.params, self.first, self.second):
            if p.grad is None:
                continue
            m.mul_(b1).add_(p.grad, alpha=1.0 - b1)
            v.mul_(b2).addcmul_(p.grad, p.grad, value=1.0 - b2)
            p.addcdiv_(m, (v.sqrt() / root_correction).add_(self.eps), value=-step_size)
