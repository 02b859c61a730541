"""Anchor attribute coding on the integer grid: what encoder and decoder both compute.

Every value is an integer on the grid of 2^-FRAC_BITS value units. The hyperprior network
(an :class:`~csgs_codec.entropy.intnet.IntMLP` on the anchor cell) outputs, per attribute
type in layout order, C mean indices (units of 2^-MEAN_BITS), C scale-table indices and one
step index. For the feature f, the channel groups after the first are refined by the CARM
networks (:class:`~csgs_codec.entropy.intnet_dense.IntDenseMLP` over the decoded earlier
groups): mean index += out[:C], scale index = clip(scale + out[C:], 0, 63). Residuals are
coded with :func:`~csgs_codec.entropy.residual.encode_residuals`, anchor-major, channel-minor.
Numpy and constriction only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.entropy.intnet import IntMLP
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.entropy.residual import (
    decode_residuals,
    encode_residuals,
    reconstructed_values,
    step_size,
)
from csgs_codec.errors import FormatError

#: Value grid: integers times 2^-FRAC_BITS.
FRAC_BITS = 12
#: Network mean outputs are in units of 2^-MEAN_BITS values (grid value = idx << 6).
MEAN_BITS = 6
#: CARM inputs: decoded grid values >> CARM_INPUT_SHIFT (units of 2^-MEAN_BITS), clipped to
#: +-(2^CARM_INPUT_BITS - 1).
CARM_INPUT_SHIFT = FRAC_BITS - MEAN_BITS
CARM_INPUT_BITS = 12
SCALE_MAX = 63


@dataclass(frozen=True)
class EntropyParams:
    """Integer entropy parameters of one attribute type for M anchors.

    Attributes:
        mean_idx: (M, C) int64 means in units of 2^-MEAN_BITS.
        scale: (M, C) int64 table indices in [0, 63].
        step: (M,) int64 step indices (one per anchor and attribute type).
    """

    mean_idx: np.ndarray
    scale: np.ndarray
    step: np.ndarray

    def columns(self, lo: int, hi: int) -> EntropyParams:
        """The parameters of channels [lo, hi)."""
        return EntropyParams(self.mean_idx[:, lo:hi], self.scale[:, lo:hi], self.step)


def hyper_width(channels: list[int]) -> int:
    """Output width of a hyperprior for attribute types with these channel counts."""
    return sum(2 * c + 1 for c in channels)


def split_hyper_outputs(out: np.ndarray, channels: list[int]) -> list[EntropyParams]:
    """(M, O) network outputs -> one :class:`EntropyParams` per attribute type, in order."""
    params, col = [], 0
    for c in channels:
        params.append(EntropyParams(out[:, col:col + c], out[:, col + c:col + 2 * c],
                                    out[:, col + 2 * c]))
        col += 2 * c + 1
    return params


def hyper_params(net: IntMLP, cells: np.ndarray, channels: list[int],
                 chunk: str | None = None) -> list[EntropyParams]:
    """Run the hyperprior on (M, 3) integer cells; one :class:`EntropyParams` per type.

    Raises FormatError (naming ``chunk``) when the network's width does not fit the layout.
    """
    if net.out_width != hyper_width(channels):
        raise FormatError(f"hyperprior has {net.out_width} outputs, the layout needs "
                          f"{hyper_width(channels)}", chunk=chunk)
    return split_hyper_outputs(net.forward(cells), channels)


def group_bounds(channels: int, groups: int) -> list[tuple[int, int]]:
    """Channel ranges of ``groups`` groups: group g is [g C // G, (g + 1) C // G)."""
    return [(g * channels // groups, (g + 1) * channels // groups) for g in range(groups)]


def refine(params: EntropyParams, net: IntDenseMLP, decoded: np.ndarray) -> EntropyParams:
    """CARM step: add the network's outputs over ``decoded`` (M, D) grid values."""
    c = params.mean_idx.shape[1]
    if net.in_width != decoded.shape[1] or net.out_width != 2 * c:
        raise FormatError(f"CARM network ({net.in_width} -> {net.out_width}) does not fit "
                          f"{decoded.shape[1]} decoded channels and a group of {c}")
    out = net.forward(decoded)
    return EntropyParams(params.mean_idx + out[:, :c],
                         np.clip(params.scale + out[:, c:], 0, SCALE_MAX), params.step)


def _flat(params: EntropyParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = params.mean_idx.shape[1]
    mean = (params.mean_idx << (FRAC_BITS - MEAN_BITS)).reshape(-1)
    return mean, params.scale.reshape(-1), np.repeat(params.step, c)


def encode_block(values: np.ndarray, params: EntropyParams) -> tuple[bytes, np.ndarray]:
    """Code (N, C) grid integers; returns (residual stream, (N, C) decoder reconstruction)."""
    mean, scale, step = _flat(params)
    flat = values.reshape(-1)
    recon = reconstructed_values(flat, mean, step).reshape(values.shape)
    return encode_residuals(flat, mean, scale, step), recon


def decode_block(stream: bytes, params: EntropyParams, *, chunk: str,
                 base_offset: int = 0) -> np.ndarray:
    """Decode :func:`encode_block`'s stream: -> (N, C) int64 grid values."""
    mean, scale, step = _flat(params)
    values = decode_residuals(stream, mean, scale, step, chunk=chunk, base_offset=base_offset)
    return values.reshape(params.mean_idx.shape)


def encode_features(values: np.ndarray, params: EntropyParams,
                    carm: list[IntDenseMLP]) -> tuple[list[bytes], np.ndarray]:
    """Code (M, F) feature grid values group by group (len(carm) + 1 groups).

    Returns:
        (one residual stream per group, (M, F) int64 reconstruction).
    """
    recon = np.zeros(values.shape, dtype=np.int64)
    streams = []
    for g, (lo, hi) in enumerate(group_bounds(values.shape[1], len(carm) + 1)):
        p = params.columns(lo, hi)
        if g:
            p = refine(p, carm[g - 1], recon[:, :lo])
        stream, recon[:, lo:hi] = encode_block(values[:, lo:hi], p)
        streams.append(stream)
    return streams, recon


def decode_features(streams: list[tuple[bytes, int]], params: EntropyParams,
                    carm: list[IntDenseMLP], *, chunk: str) -> np.ndarray:
    """Decode :func:`encode_features`' streams ((bytes, absolute offset) each) -> (M, F)."""
    m, f = params.mean_idx.shape
    recon = np.zeros((m, f), dtype=np.int64)
    for g, (lo, hi) in enumerate(group_bounds(f, len(carm) + 1)):
        p = params.columns(lo, hi)
        if g:
            p = refine(p, carm[g - 1], recon[:, :lo])
        data, offset = streams[g]
        recon[:, lo:hi] = decode_block(data, p, chunk=chunk, base_offset=offset)
    return recon


def masked_params(params: EntropyParams, mask: np.ndarray) -> EntropyParams:
    """Offset parameters of the kept offsets only: (M, 3K) + (M, K) mask -> (n_kept, 3)."""
    m, k = mask.shape
    return EntropyParams(params.mean_idx.reshape(m, k, 3)[mask],
                         params.scale.reshape(m, k, 3)[mask],
                         np.broadcast_to(params.step[:, None], (m, k))[mask])


def step_values(step_idx: np.ndarray) -> np.ndarray:
    """Quantization steps in value units: (N,) step indices -> (N,) float64."""
    return np.ldexp(step_size(step_idx).astype(np.float64), -FRAC_BITS)
