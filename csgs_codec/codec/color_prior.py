"""The color layer's INR hyperprior (FORMAT §12.19) at work: the per-channel priors its
network gives the float streams. Numpy only; the CHYP payload is
:mod:`csgs_codec.chunks.color_prior`'s, the fit :mod:`csgs_codec.model.color_hyperprior`'s.

The network reads each Gaussian's integer grid cell (the geometry's cell; far outliers, which
have none, read cell (0, 0, 0)). Modelled channel j of a stream gets the prior
``mean = (out[:, j] + 32) >> 6`` (the mean rounded half up to whole steps) and
``scale = out[:, M + j]``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from csgs_codec.chunks.color_prior import MEAN_BITS, ColorPrior, stream_layout
from csgs_codec.codec.float_stream import ChannelPrior
from csgs_codec.entropy.intnet import IntMLP


def modelled_streams(prior: ColorPrior, names: list[str]) -> set[str]:
    """The streams among ``names`` with at least one channel the prior models."""
    return {name for (name, _), on in zip(stream_layout(names), prior.mask) if on}


def prior_cells(cells: np.ndarray, far_count: int) -> np.ndarray:
    """The network input of every Gaussian in decoded order: (N, 3) int64, the grid cells of
    the first N - far_count and (0, 0, 0) for the far outliers after them."""
    return np.concatenate([np.asarray(cells, np.int64).reshape(-1, 3),
                           np.zeros((far_count, 3), np.int64)])


def channel_priors(prior: ColorPrior, cells: np.ndarray, names: list[str]
                   ) -> dict[str, dict[int, ChannelPrior]]:
    """Run the network on ``cells`` (N, 3): stream -> channel -> :class:`ChannelPrior`."""
    out = prior.net.forward(cells)
    modelled = [lc for lc, on in zip(stream_layout(names), prior.mask) if on]
    m = len(modelled)
    # Round the means in place and hand out column views: at millions of Gaussians, copies
    # of these (N, 2M) outputs would cost as much memory and time as the network itself.
    means = out[:, :m]
    means += 1 << (MEAN_BITS - 1)
    means >>= MEAN_BITS
    result: dict[str, dict[int, ChannelPrior]] = {name: {} for name in names}
    for j, (name, c) in enumerate(modelled):
        result[name][c] = ChannelPrior(out[:, j], out[:, m + j])
    return result


def keep_outputs(prior: ColorPrior, keep: np.ndarray) -> ColorPrior:
    """The prior restricted to the modelled channels where ``keep`` (M,) is true: the network's
    last layer loses the other channels' rows, so the kept outputs are unchanged."""
    keep = np.asarray(keep, bool)
    rows = np.concatenate([keep, keep])
    last = prior.net.layers[-1]
    layer = replace(last, weights=last.weights[rows], biases=last.biases[rows])
    net = IntMLP(prior.net.pos_bits, prior.net.num_freqs, prior.net.act_bits,
                 prior.net.layers[:-1] + (layer,), prior.net.out_lo[rows],
                 prior.net.out_hi[rows])
    mask = prior.mask.copy()
    mask[np.flatnonzero(mask)[~keep]] = False
    return ColorPrior(mask, net)
