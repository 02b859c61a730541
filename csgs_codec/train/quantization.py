"""Quantization-aware training terms (torch): the noise proxy, the rate proxy and the
quality-aware weights of stage 2.

* :func:`add_quantization_noise`: s + U(-Q/2, Q/2), the differentiable stand-in for rounding
  to a grid of step Q while training.
* :func:`gaussian_rate_bits`: the bits a value costs under a Gaussian (mu, sigma) quantized
  with step q, -log2(Phi((x - mu + q/2) / sigma) - Phi((x - mu - q/2) / sigma)). Evaluated at
  noisy values it estimates the size the range coder will produce with the frozen Gaussian
  tables (csgs_codec.entropy.tables) for the rounded values. Clamps: sigma to
  [0.11 q, 128 q], the range of the frozen table family (the coder can do no better nor
  cheaper), and the probability to at least 2^-30, which keeps bits finite and gradients
  bounded for values far in the tail.
* :func:`quality_aware_weights`: w = 1 if 1 - norm(q_f) >= T else 1 - norm(q_f), T = 0.65,
  where q_f is each anchor's color quantization step from stage 1 and norm is min-max
  normalisation over the anchors: norm(q) = (q - min q) / (max q - min q), 0 for every
  anchor when all steps are equal. Anchors with coarse color (large q_f, poorly
  reconstructed) get smaller semantic features, so they weigh less in the rendered map.
  Given the range [low, high] of steps the codec can assign, norm is instead measured on
  that range, on a log scale: norm(q) = log(q / low) / log(high / low), clipped to [0, 1].
  The anchor codec's steps sit on a 1/8-octave grid, and min-max over anchors whose steps
  differ by one grid point (7%) would give half of them w = 0 (measured: 153 of 277 anchors
  never trained their semantic feature); on the codec's range such anchors get w = 1.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from csgs_codec.entropy.tables import SIGMA_MAX, SIGMA_MIN
from csgs_codec.errors import InputError

#: T of the quality-aware weighting.
QUALITY_THRESHOLD = 0.65
#: Smallest probability :func:`gaussian_rate_bits` assigns (at most 30 bits per value).
MIN_PROBABILITY = 2.0**-30


def add_quantization_noise(values: torch.Tensor, step: float | torch.Tensor = 1.0, *,
                           generator: torch.Generator | None = None) -> torch.Tensor:
    """values + U(-step/2, step/2), elementwise; differentiable in ``values``.

    Args:
        values: any shape.
        step: the quantization step Q (scalar or broadcastable tensor, > 0).
        generator: torch generator for reproducible noise (on ``values``' device).

    Returns:
        A tensor of ``values``' shape and dtype.
    """
    noise = torch.rand(values.shape, generator=generator, dtype=values.dtype,
                       device=values.device) - 0.5
    if isinstance(step, (int, float)):  # one fused multiply-add
        return torch.add(values, noise, alpha=step)
    return values + noise * step


def _clamped_bin_mass(values: torch.Tensor, mean: torch.Tensor, sigma: torch.Tensor,
                      step: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """2 x the clamped bin mass, erfc(a) - erfc(b) with a, b = (|x - mu| -+ q/2) /
    (sigma sqrt 2) (i.e. 2 (Phi((q/2 - d) / sigma) - Phi((-q/2 - d) / sigma))), and what
    its gradient needs: (mass, clamped sigma, x - mu, a, b)."""
    clamped = torch.clamp(sigma, SIGMA_MIN * step, SIGMA_MAX * step)
    difference = values - mean
    distance = torch.abs(difference)
    half = 0.5 * step
    inverse = torch.reciprocal(clamped * math.sqrt(2.0))
    a = (distance - half) * inverse
    b = (distance + half) * inverse
    mass = torch.clamp(torch.special.erfc(a) - torch.special.erfc(b),
                       min=2.0 * MIN_PROBABILITY)
    return mass, clamped, difference, a, b


class _RateBits(torch.autograd.Function):
    """:func:`gaussian_rate_bits` with its gradient written out rather than recorded: a
    third fewer operators a step, which is what a GPU's training step waits on. With
    m = erfc(a) - erfc(b) and g = -dL/dbits * 2 / (sqrt(pi) ln 2 m) (0 where m is clamped):
    dL/dx = g (e^-b^2 - e^-a^2) / (sigma sqrt 2) sign(x - mu), dL/dmu = -dL/dx,
    dL/dsigma = g (a e^-a^2 - b e^-b^2) / sigma inside the sigma clamp, 0 outside."""

    @staticmethod
    def forward(ctx, values, mean, sigma, step):
        mass, clamped, difference, a, b = _clamped_bin_mass(values, mean, sigma, step)
        ctx.save_for_backward(mass, clamped, difference, a, b, sigma)
        ctx.shapes = (values.shape, mean.shape, sigma.shape)
        return 1.0 - torch.log2(mass)

    @staticmethod
    def backward(ctx, grad):
        mass, clamped, difference, a, b, sigma = ctx.saved_tensors
        scale = grad * (-2.0 / (math.sqrt(math.pi) * math.log(2.0))) / mass
        g = torch.where(mass > 2.0 * MIN_PROBABILITY, scale, 0.0)
        exp_a = torch.exp(-(a * a))
        exp_b = torch.exp(-(b * b))
        inverse = torch.reciprocal(clamped)
        grad_values = grad_mean = grad_sigma = None
        if ctx.needs_input_grad[0] or ctx.needs_input_grad[1]:
            slope = g * (exp_b - exp_a) * inverse * (1.0 / math.sqrt(2.0))
            slope = slope * torch.sign(difference)
            if ctx.needs_input_grad[0]:
                grad_values = slope.sum_to_size(ctx.shapes[0])
            if ctx.needs_input_grad[1]:
                grad_mean = -slope.sum_to_size(ctx.shapes[1])
        if ctx.needs_input_grad[2]:
            grad_sigma = torch.where(clamped == sigma,
                                     g * (a * exp_a - b * exp_b) * inverse, 0.0)
            grad_sigma = grad_sigma.sum_to_size(ctx.shapes[2])
        return grad_values, grad_mean, grad_sigma, None


def gaussian_bin_probability(values: torch.Tensor, mean: torch.Tensor, sigma: torch.Tensor,
                             step: torch.Tensor | float) -> torch.Tensor:
    """Gaussian mass of the width-``step`` bin centred on each value (clamps: module notes).

    Args:
        values, mean, sigma, step: broadcastable tensors, same units (sigma, step > 0).

    Returns:
        Probabilities in [2^-30, 1], the broadcast shape. The mass is measured on the side of
        the mean where the CDF has full relative precision (|x - mu| mirrored below the mean).
    """
    step = torch.as_tensor(step, dtype=values.dtype, device=values.device)
    return 0.5 * _clamped_bin_mass(values, mean, sigma, step)[0]


def gaussian_rate_bits(values: torch.Tensor, mean: torch.Tensor, sigma: torch.Tensor,
                       step: torch.Tensor | float) -> torch.Tensor:
    """Bits of each value under N(mean, sigma) quantized with ``step``: -log2 of
    :func:`gaussian_bin_probability`, the broadcast shape; differentiable in every input."""
    step = torch.as_tensor(step, dtype=values.dtype, device=values.device)
    if step.requires_grad:  # the written-out gradient has none for the step
        return 1.0 - torch.log2(_clamped_bin_mass(values, mean, sigma, step)[0])
    return _RateBits.apply(values, mean, sigma, step)


def quality_aware_weights(color_steps: torch.Tensor | np.ndarray,
                          threshold: float = QUALITY_THRESHOLD, *,
                          step_range: tuple[float, float] | None = None) -> torch.Tensor:
    """Per-anchor weights of the rendered semantic feature (module notes).

    Args:
        color_steps: (N,) positive color quantization steps q_f, one per anchor.
        threshold: T.
        step_range: (low, high) steps the codec can assign (0 < low < high): normalise on
            that range, log scale; None: min-max over the anchors.

    Returns:
        (N,) weights in [0, 1], no gradient (the steps are fixed by stage 1), on the input
        tensor's device (the CPU for numpy input); dtype float32 for numpy input, else the
        input's.

    Raises:
        InputError: a step that is not finite.
    """
    device = (color_steps.device if torch.is_tensor(color_steps)
              else torch.device("cpu"))  # cpu: numpy steps are in host memory
    steps = torch.as_tensor(color_steps, device=device).detach()
    if not steps.dtype.is_floating_point:
        steps = steps.to(torch.float32)
    if steps.ndim != 1:
        raise InputError(f"color steps must be (N,), got {tuple(steps.shape)}",
                         property="color_steps")
    if steps.numel() == 0:
        return steps.clone()
    if not bool(torch.all(torch.isfinite(steps))):
        raise InputError("color steps must be finite", property="color_steps")
    if step_range is not None:
        low, high = (float(v) for v in step_range)
        if not (0 < low < high < math.inf):
            raise InputError(f"step range must satisfy 0 < low < high, got {step_range}",
                             property="step_range")
        if not bool(torch.all(steps > 0)):
            raise InputError("color steps must be positive", property="color_steps")
        norm = torch.clamp(torch.log(steps / low) / math.log(high / low), 0.0, 1.0)
    else:
        low, high = steps.min(), steps.max()
        spread = high - low
        norm = (steps - low) / spread if float(spread) > 0 else torch.zeros_like(steps)
    quality = 1.0 - norm
    return torch.where(quality >= threshold, torch.ones_like(quality), quality)
