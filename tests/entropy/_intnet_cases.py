"""Shared builders of random integer networks for the entropy tests."""

from __future__ import annotations

import numpy as np

from csgs_codec.entropy.intnet import IntLayer, IntMLP


def random_network(seed: int = 0, num_freqs: int = 4, width: int = 64, depth: int = 3,
                   weight_bits: int = 8, act_bits: int = 12, pos_bits: int = 16) -> IntMLP:
    """A random 8-bit network with outputs (mean, scale index, step index)."""
    rng = np.random.default_rng(seed)
    widths = [6 * num_freqs] + [width] * (depth - 1) + [3]
    top = 1 << (weight_bits - 1)
    layers = tuple(IntLayer(rng.integers(-top, top, (widths[i + 1], widths[i])),
                            rng.integers(-(1 << 16), 1 << 16, widths[i + 1]),
                            int(rng.integers(8, 14)), weight_bits)
                   for i in range(depth))
    return IntMLP(pos_bits, num_freqs, act_bits, layers, np.array([-(1 << 20), 0, 0]),
                  np.array([1 << 20, 63, 175]))


def random_positions(n: int, seed: int = 1, pos_bits: int = 16) -> np.ndarray:
    """(n, 3) int64 positions in [0, 2^pos_bits)."""
    return np.random.default_rng(seed).integers(0, 1 << pos_bits, (n, 3))
