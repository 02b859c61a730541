"""Pieces shared by the hyperprior fits (anchor and color): the MLP shape, the bin-mass rate
estimate, a plain Adam, gradient clipping and output scaling before integer export."""

from __future__ import annotations

import copy
import math

import numpy as np
import torch

from csgs_codec.entropy.tables import SCALE_COUNT, SIGMA_MAX, SIGMA_MIN

#: Highest scale-table index of the frozen Gaussian family.
SCALE_MAX = SCALE_COUNT - 1
#: Scale (and step) outputs are trained in units of 1/8 index, so Adam moves them gently.
INDEX_UNIT = 8.0
#: Gradients are scaled down to this total norm. Losses are in bits per anchor or Gaussian;
#: ordinary fits stay below about 100, so the clip only catches runaway steps.
GRAD_CLIP_NORM = 1000.0


def mlp(sizes: list[int], *, device: torch.device | str) -> torch.nn.Sequential:
    """``Linear, ReLU, ..., Linear`` through the layer widths ``sizes``, on ``device``."""
    layers: list[torch.nn.Module] = []
    for i in range(len(sizes) - 1):
        layers.append(torch.nn.Linear(sizes[i], sizes[i + 1], device=device))
        if i < len(sizes) - 2:
            layers.append(torch.nn.ReLU())
    return torch.nn.Sequential(*layers)


def table_sigma(scale_idx: torch.Tensor) -> torch.Tensor:
    """The Gaussian sigma (in steps) of a continuous scale-table index, clipped to [0, 63]."""
    ratio = math.log(SIGMA_MAX / SIGMA_MIN) / SCALE_MAX
    return SIGMA_MIN * torch.exp(torch.clamp(scale_idx, 0.0, float(SCALE_MAX)) * ratio)


def scale_index_for_std(std_steps: np.ndarray) -> np.ndarray:
    """The (continuous) scale-table index of a Gaussian of standard deviation ``std_steps``
    quantization steps, clipped to [0, 63]: where a fit's scale outputs start."""
    ratio = math.log(SIGMA_MAX / SIGMA_MIN) / SCALE_MAX
    return np.clip(np.log(np.maximum(std_steps, SIGMA_MIN) / SIGMA_MIN) / ratio, 0, SCALE_MAX)


def num_freqs_for(pos_bits: int) -> int:
    """Embedding octaves for cells of ``pos_bits`` bits: periods from the whole grid down to
    2^(pos_bits - L) cells, at most 10 octaves and never below a period of 2 cells."""
    return max(1, min(10, pos_bits - 1))


def gaussian_bin_bits(values, mean, scale_idx, step, noise) -> torch.Tensor:
    """Estimated bits of each value: -log2 of the Gaussian mass over its (noisy) bin.

    ``values``, ``mean`` and ``step`` share units; ``noise`` (in steps) is the uniform
    relaxation of rounding, or 0 for values that are already integers on the step grid.
    """
    s = table_sigma(scale_idx)
    y = values - mean
    # A unit step and no noise leave y as it is (x / 1 and x + 0 are exact): skipping them
    # spares the integer-valued fits four operators a step, forward and backward.
    if not (isinstance(step, (int, float)) and step == 1):
        y = y / step
    if not (isinstance(noise, (int, float)) and noise == 0):
        y = y + noise
    mass = torch.special.ndtr((y + 0.5) / s) - torch.special.ndtr((y - 0.5) / s)
    return -torch.log2(torch.clamp(mass, min=1e-9))


class Adam:
    """Adam (Kingma & Ba) in plain tensor ops: torch.optim imports torch._dynamo on first
    use, which costs seconds of encoder start-up for nothing here."""

    def __init__(self, params, lr: float, betas=(0.9, 0.999), eps: float = 1e-8) -> None:
        self.params = list(params)
        self.lr, self.betas, self.eps, self.t = lr, betas, eps, 0
        self.m = [torch.zeros_like(p) for p in self.params]
        self.v = [torch.zeros_like(p) for p in self.params]

    def zero_grad(self) -> None:
        """Forget the gradients of the last step."""
        for p in self.params:
            p.grad = None

    def step(self) -> None:
        """One update of every parameter that has a gradient."""
        b1, b2 = self.betas
        self.t += 1
        c1, c2 = 1 - b1 ** self.t, 1 - b2 ** self.t
        with torch.no_grad():
            for p, m, v in zip(self.params, self.m, self.v):
                if p.grad is None:
                    continue
                m.mul_(b1).add_(p.grad, alpha=1 - b1)
                v.mul_(b2).addcmul_(p.grad, p.grad, value=1 - b2)
                p.addcdiv_(m / c1, (v / c2).sqrt_().add_(self.eps), value=-self.lr)


def clip_gradients(params: list[torch.Tensor], max_norm: float) -> float:
    """Scale the gradients of ``params`` down to total L2 norm ``max_norm`` if above it;
    returns the norm before clipping (inf or nan when a gradient is not finite)."""
    grads = [p.grad for p in params if p.grad is not None]
    if not grads:
        return 0.0
    norm = float(torch.sqrt(sum((g.double() ** 2).sum() for g in grads)))
    if math.isfinite(norm) and norm > max_norm:
        with torch.no_grad():
            for g in grads:
                g.mul_(max_norm / norm)
    return norm


def scaled_outputs(net: torch.nn.Sequential, row_scale: np.ndarray) -> torch.nn.Sequential:
    """A copy of ``net`` whose last layer outputs ``row_scale`` (O,) times the original."""
    out = copy.deepcopy(net)
    scale = torch.as_tensor(np.asarray(row_scale, dtype=np.float64),
                            device=out[-1].weight.device).float()
    with torch.no_grad():
        out[-1].weight.mul_(scale[:, None])
        out[-1].bias.mul_(scale)
    return out
