"""The anchor codec's per-anchor attribute chunks (FORMAT §17.6, §17.8-§17.10), both
directions. Values are integers on the grid of 2^-12 value units (§17.2), coded with the
hyperprior's entropy parameters (:mod:`csgs_codec.entropy.anchor_attributes`):

- AMSK: the (M, K) offset masks (1 = kept), the context-coded bit stream of
  :mod:`csgs_codec.entropy.offset_masks`.
- AFEA: the (M, F) features, a count G, then one length-prefixed residual stream per CARM
  group, each anchor-major and channel-minor.
- AOFF: the kept offsets only (each anchor in order, its kept slots in increasing order, the
  3 axes), one residual stream, the whole payload; masked offsets decode as 0.
- ASCL: the (M, 6) scaling values, one residual stream, the whole payload.

Writers return the payload and the float32 values a decoder returns; readers return those
values.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.chunks.stream_list import read_stream_list, stream_list_payload
from csgs_codec.entropy.anchor_attributes import (
    FRAC_BITS,
    EntropyParams,
    decode_block,
    decode_features,
    encode_block,
    encode_features,
    masked_params,
)
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.entropy.offset_masks import decode_masks, encode_masks
from csgs_codec.entropy.residual import from_grid, to_grid
from csgs_codec.errors import FormatError


def grid_floats(values: np.ndarray) -> np.ndarray:
    """Grid integers (any shape) -> the float32 values a decoder outputs (same shape)."""
    return from_grid(values.reshape(-1), FRAC_BITS).astype(np.float32).reshape(values.shape)


def _finite(values: np.ndarray, name: str, chunk: str) -> np.ndarray:
    """``values``, or FormatError naming ``chunk`` when one overflows float32."""
    if not np.all(np.isfinite(values)):
        raise FormatError(f"decoded {name} overflow float32", chunk=chunk)
    return values


def offset_mask_payload(mask: np.ndarray) -> bytes:
    """The AMSK payload of the (M, K) bool offset masks."""
    return encode_masks(mask)


def read_offset_masks(container, count: int, slots: int) -> np.ndarray:
    """The (count, slots) bool offset masks of ``container``'s AMSK (M anchors, K slots).

    Raises:
        FormatError: naming AMSK and the byte offset.
    """
    data, offset = container.single_payload("AMSK")
    return decode_masks(data, count, slots, chunk="AMSK", base_offset=offset)


def anchor_feature_payload(features: np.ndarray, params: EntropyParams,
                           carm: list[IntDenseMLP]) -> tuple[bytes, np.ndarray]:
    """(AFEA payload, decoded (M, F) float32 features) of ``features`` (M, F), value units,
    coded in len(carm) + 1 groups with the hyperprior's feature ``params`` refined by the
    CARM networks ``carm``."""
    m, f = features.shape
    streams, decoded = encode_features(to_grid(features, FRAC_BITS).reshape(m, f), params,
                                       carm)
    return stream_list_payload(streams), grid_floats(decoded)


def read_anchor_features(container, params: EntropyParams,
                         carm: list[IntDenseMLP]) -> np.ndarray:
    """The (M, F) float32 features of ``container``'s AFEA, decoded with the hyperprior's
    feature ``params`` (M anchors, F channels) and the CARM networks ``carm``.

    Raises:
        FormatError: naming AFEA and the byte offset (another group count, a malformed
            stream, a value beyond float32).
    """
    data, offset = container.single_payload("AFEA")
    streams = read_stream_list(data, offset, "AFEA", len(carm) + 1)
    values = decode_features(streams, params, carm, chunk="AFEA")
    return _finite(grid_floats(values), "features", "AFEA")


def anchor_offset_payload(offsets: np.ndarray, mask: np.ndarray,
                          params: EntropyParams) -> tuple[bytes, np.ndarray]:
    """(AOFF payload, decoded (M, K, 3) float32 offsets, masked ones 0) of ``offsets``
    (M, K, 3), value units, whose slots ``mask`` (M, K) keeps, coded with the hyperprior's
    offset ``params`` (M, 3K)."""
    kept = to_grid(offsets[mask].reshape(-1), FRAC_BITS).reshape(-1, 3)
    stream, decoded_kept = encode_block(kept, masked_params(params, mask))
    decoded = np.zeros(offsets.shape, dtype=np.float32)
    decoded[mask] = grid_floats(decoded_kept)
    return stream, decoded


def read_anchor_offsets(container, params: EntropyParams, mask: np.ndarray) -> np.ndarray:
    """The (M, K, 3) float32 offsets of ``container``'s AOFF, decoded with the hyperprior's
    offset ``params`` (M, 3K) for the slots ``mask`` (M, K) keeps; masked offsets are 0.

    Raises:
        FormatError: naming AOFF and the byte offset.
    """
    data, offset = container.single_payload("AOFF")
    kept = decode_block(data, masked_params(params, mask), chunk="AOFF", base_offset=offset)
    offsets = np.zeros((*mask.shape, 3), dtype=np.float32)
    offsets[mask] = grid_floats(kept)
    return _finite(offsets, "offsets", "AOFF")


def anchor_scaling_payload(scaling: np.ndarray,
                           params: EntropyParams) -> tuple[bytes, np.ndarray]:
    """(ASCL payload, decoded (M, 6) float32 scaling) of ``scaling`` (M, 6), value units,
    coded with the hyperprior's scaling ``params``."""
    stream, decoded = encode_block(to_grid(scaling.reshape(-1), FRAC_BITS)
                                   .reshape(len(scaling), 6), params)
    return stream, grid_floats(decoded)


def read_anchor_scaling(container, params: EntropyParams) -> np.ndarray:
    """The (M, 6) float32 scaling of ``container``'s ASCL, decoded with the hyperprior's
    scaling ``params``.

    Raises:
        FormatError: naming ASCL and the byte offset.
    """
    data, offset = container.single_payload("ASCL")
    values = decode_block(data, params, chunk="ASCL", base_offset=offset)
    return _finite(grid_floats(values), "scaling", "ASCL")
