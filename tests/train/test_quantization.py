"""Quantization-aware terms: noise proxy, rate proxy against the real coder, QWM weights."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from csgs_codec.entropy.residual import encode_symbols
from csgs_codec.entropy.tablegen import sigma_grid
from csgs_codec.errors import InputError
from csgs_codec.train.quantization import (
    MIN_PROBABILITY,
    add_quantization_noise,
    gaussian_rate_bits,
    quality_aware_weights,
)


def test_quality_weights_follow_the_formula():
    steps = torch.tensor([1.0, 2.0, 3.0, 4.0, 5.0])  # norm = 0, .25, .5, .75, 1
    weights = quality_aware_weights(steps)
    # 1 - norm = 1, .75, .5, .25, 0: kept as 1 while >= 0.65, else 1 - norm.
    np.testing.assert_allclose(weights.numpy(), [1.0, 1.0, 0.5, 0.25, 0.0])


def test_quality_weights_threshold_is_inclusive_and_settable():
    steps = torch.tensor([0.0, 0.35, 1.0], dtype=torch.float64)  # 1 - norm = 1, .65, 0
    np.testing.assert_allclose(quality_aware_weights(steps).numpy(), [1.0, 1.0, 0.0])
    np.testing.assert_allclose(quality_aware_weights(steps, threshold=0.9).numpy(),
                               [1.0, 0.65, 0.0])


def test_quality_weights_of_equal_steps_are_one_and_carry_no_gradient():
    steps = torch.full((4,), 0.3, requires_grad=True)
    weights = quality_aware_weights(steps)
    np.testing.assert_array_equal(weights.numpy(), 1.0)
    assert not weights.requires_grad
    assert quality_aware_weights(np.array([1.0, 3.0])).dtype == torch.float64


def test_quality_weights_reject_non_finite_steps():
    with pytest.raises(InputError, match="finite"):
        quality_aware_weights(torch.tensor([1.0, math.inf]))


def test_noise_stays_within_half_a_step_and_is_reproducible():
    values = torch.linspace(-3, 3, 20000, dtype=torch.float64)
    noisy = add_quantization_noise(values, 2.0, generator=torch.Generator().manual_seed(3))
    noise = noisy - values
    assert noise.abs().max().item() <= 1.0
    assert abs(noise.mean().item()) < 0.02 and noise.var().item() == pytest.approx(1 / 3,
                                                                                   rel=0.05)
    again = add_quantization_noise(values, 2.0, generator=torch.Generator().manual_seed(3))
    assert torch.equal(noisy, again)


def test_noise_passes_the_gradient_through():
    values = torch.zeros(5, requires_grad=True)
    add_quantization_noise(values).sum().backward()
    np.testing.assert_array_equal(values.grad.numpy(), 1.0)


def test_rate_bits_of_a_value_at_the_mean_is_the_central_bin():
    # P = Phi(0.5) - Phi(-0.5) = erf(0.5 / sqrt 2) for sigma = step = 1.
    bits = gaussian_rate_bits(torch.tensor(0.0), torch.tensor(0.0), torch.tensor(1.0), 1.0)
    assert bits.item() == pytest.approx(-math.log2(math.erf(0.5 / math.sqrt(2))))


def test_rate_bits_far_in_the_tail_are_clamped_and_finite():
    values = torch.tensor([1e3, -1e6], dtype=torch.float64, requires_grad=True)
    bits = gaussian_rate_bits(values, torch.zeros(2, dtype=torch.float64),
                              torch.ones(2, dtype=torch.float64), 1.0)
    np.testing.assert_allclose(bits.detach().numpy(), -math.log2(MIN_PROBABILITY))
    bits.sum().backward()
    assert torch.all(torch.isfinite(values.grad))


def test_rate_bits_clamp_sigma_to_the_table_range():
    tiny = gaussian_rate_bits(torch.tensor(0.0), torch.tensor(0.0), torch.tensor(1e-6), 1.0)
    floor = gaussian_rate_bits(torch.tensor(0.0), torch.tensor(0.0), torch.tensor(0.11), 1.0)
    assert tiny.item() == pytest.approx(floor.item())


def test_rate_bits_grow_with_the_distance_from_the_mean():
    values = torch.tensor([0.0, 1.0, 2.0, 4.0])
    bits = gaussian_rate_bits(values, torch.zeros(4), torch.full((4,), 2.0), 1.0)
    assert torch.all(bits[1:] > bits[:-1])


def test_noise_proxy_rate_matches_the_coded_size_within_five_percent():
    rng = np.random.default_rng(7)
    n = 50_000
    table = rng.integers(8, 56, n)  # sigma / q from 0.27 to 40 steps
    step = rng.choice([0.25, 1.0, 3.0], n)
    sigma = sigma_grid()[table] * step
    mean = rng.normal(0.0, 20.0, n)
    values = mean + sigma * rng.standard_normal(n)
    residuals = np.rint((values - mean) / step).astype(np.int64)
    coded_bits = 8 * len(encode_symbols(residuals, table))
    noisy = add_quantization_noise(torch.from_numpy(values), torch.from_numpy(step),
                                   generator=torch.Generator().manual_seed(0))
    proxy_bits = gaussian_rate_bits(noisy, torch.from_numpy(mean), torch.from_numpy(sigma),
                                    torch.from_numpy(step)).sum().item()
    assert proxy_bits == pytest.approx(coded_bits, rel=0.05)


def test_quality_weights_on_the_codecs_step_range_use_a_log_scale():
    from csgs_codec.train.quantization import quality_aware_weights

    steps = np.array([0.25, 1.0, 1.09, 2.0, 4.0], np.float32)
    weights = quality_aware_weights(steps, step_range=(0.25, 4.0)).numpy()
    # norm = log(q / 0.25) / log(16): 0, 0.5, 0.53, 0.75, 1 -> 1 - norm = 1, 0.5, 0.47, ...
    np.testing.assert_allclose(weights, [1.0, 0.5, 1 - np.log(1.09 / 0.25) / np.log(16),
                                         0.25, 0.0], atol=1e-6)
    # Two steps one grid point apart: min-max would give one of them w = 0.
    close = np.array([1.0, 2 ** 0.125], np.float32)
    assert quality_aware_weights(close).numpy().tolist() == [1.0, 0.0]
    assert quality_aware_weights(close, step_range=(0.25, 4.0)).numpy().min() > 0.45


def test_quality_weights_refuse_a_bad_step_range():
    from csgs_codec.train.quantization import quality_aware_weights

    for bad in ((0.0, 1.0), (2.0, 1.0)):
        with pytest.raises(InputError, match="step range"):
            quality_aware_weights(np.ones(3, np.float32), step_range=bad)
