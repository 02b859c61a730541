"""The color hyperprior's chunk `CHYP` (FORMAT §12.19), both directions: a version, the mask
of the color streams' channels the network models, then the integer network (§16.4).

The color float streams, in order (dc, rest1.., opacity, scale, rot), have T channels in
all; the mask says which of them the network models. With M modelled channels the network
has 2M outputs per Gaussian: M mean indices (units of 1/64 step) then M scale-table indices.

What the network gives the float streams is here too (:func:`channel_priors`): it reads each
Gaussian's integer grid cell (the geometry's cell; far outliers, which have none, read cell
(0, 0, 0)); modelled channel j of a stream gets the prior ``mean = (out[:, j] + 32) >> 6``
(the mean rounded half up to whole steps) and ``scale = out[:, M + j]``. Numpy only; the fit
is :mod:`csgs_codec.model.color_hyperprior`'s.
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, replace

import numpy as np

from csgs_codec.attributes.float_stream import ChannelPrior
from csgs_codec.chunks.color_streams import STREAM_CHANNELS
from csgs_codec.entropy.intnet import IntMLP
from csgs_codec.entropy.intnet_bytes import intnet_from_bytes, intnet_to_bytes
from csgs_codec.entropy.tables import SCALE_COUNT
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter

CHYP_VERSION = 1
#: Mean outputs are in units of 2^-MEAN_BITS steps, within +-MEAN_LIMIT.
MEAN_BITS = 6
MEAN_LIMIT = 1 << 40
#: Scale outputs index the frozen Gaussian family.
SCALE_MAX = SCALE_COUNT - 1
#: Widest grid (bits per axis) the network's inputs may come from.
MAX_POS_BITS = 32


@dataclass(frozen=True)
class ColorPrior:
    """A fitted color hyperprior.

    Attributes:
        mask: (T,) bool, which channels of the color streams (in stream order) it models.
        net: the integer network, 2 * mask.sum() outputs.
    """

    mask: np.ndarray
    net: IntMLP


def stream_layout(names: list[str]) -> list[tuple[str, int]]:
    """(stream, channel) of every channel of the color streams ``names``, in order."""
    return [(name, c) for name in names for c in range(STREAM_CHANNELS[name])]


def color_prior_payload(prior: ColorPrior) -> bytes:
    """The CHYP payload: u8 version, varint T, the mask (ceil(T / 8) bytes, channel i in bit
    i mod 8 of byte i // 8), then the network payload (FORMAT §16.4)."""
    out = ByteWriter()
    out.fixed("u8", CHYP_VERSION)
    out.varint(len(prior.mask))
    out.raw(np.packbits(prior.mask.astype(np.uint8), bitorder="little").tobytes())
    out.raw(intnet_to_bytes(prior.net))
    return out.getvalue()


def prior_from_bytes(data: bytes, *, base_offset: int, names: list[str],
                     pos_bits: int) -> ColorPrior:
    """Parse a CHYP payload for the color streams ``names`` and a grid of ``pos_bits``.

    Raises:
        FormatError: unknown version, a channel count or mask that does not fit the streams,
            a bad network, or one whose width or grid does not match.
    """
    r = ByteReader(data, base_offset=base_offset, chunk="CHYP")
    version = r.fixed("u8", "version")
    if version != CHYP_VERSION:
        raise r.error(f"color hyperprior version {version} is not {CHYP_VERSION}",
                      at=base_offset)
    total = len(stream_layout(names))
    count = r.varint("channel_count", maximum=1 << 16)
    if count != total:
        raise r.error(f"the mask covers {count} channels, the color streams have {total}")
    packed = np.frombuffer(r.raw((total + 7) // 8, "channel_mask"), np.uint8)
    bits = np.unpackbits(packed, bitorder="little").astype(bool)
    if bits[total:].any():
        raise r.error("channel mask has bits set beyond the channel count")
    mask = bits[:total]
    net = intnet_from_bytes(data[r.position:], chunk="CHYP", base_offset=r.offset)
    if net.out_width != 2 * int(mask.sum()):
        raise FormatError(f"network has {net.out_width} outputs, the mask models "
                          f"{int(mask.sum())} channels (needs twice that)", chunk="CHYP",
                          offset=r.offset)
    m = int(mask.sum())
    if (np.abs(net.out_lo[:m]).max(initial=0) > MEAN_LIMIT
            or np.abs(net.out_hi[:m]).max(initial=0) > MEAN_LIMIT
            or net.out_lo[m:].min(initial=0) < 0 or net.out_hi[m:].max(initial=0) > SCALE_MAX):
        raise FormatError(f"network output clamps allow means beyond 2^40 steps/64 or scale "
                          f"indices outside 0..{SCALE_MAX}", chunk="CHYP", offset=r.offset)
    if net.pos_bits != pos_bits:
        raise FormatError(f"network pos_bits {net.pos_bits} differs from the grid's "
                          f"{pos_bits}", chunk="CHYP", offset=r.offset)
    return ColorPrior(mask, net)


def read_color_prior(container, names: list[str], grid_bits: int) -> ColorPrior:
    """The color hyperprior of ``container``'s CHYP chunk for the color streams ``names`` of
    a scene whose grid has ``grid_bits`` bits per axis (parsed, not yet evaluated).

    Raises:
        FormatError: a grid too wide for the network's inputs, or a bad payload
            (:func:`prior_from_bytes`), at the chunk's offset.
    """
    data, offset = container.single_payload("CHYP")
    pos_bits = max(grid_bits, 1)
    if pos_bits > MAX_POS_BITS:
        raise FormatError(f"the color hyperprior needs a grid of at most {MAX_POS_BITS} bits, "
                          f"the header has {pos_bits}", chunk="CHYP", offset=offset)
    return prior_from_bytes(data, base_offset=offset, names=names, pos_bits=pos_bits)


def modelled_streams(prior: ColorPrior, names: list[str]) -> set[str]:
    """The streams among ``names`` with at least one channel the prior models."""
    return {name for (name, _), on in zip(stream_layout(names), prior.mask) if on}


def prior_cells(cells: np.ndarray, far_count: int) -> np.ndarray:
    """The network input of every Gaussian in decoded order: (N, 3) int64, the grid cells of
    the first N - far_count and (0, 0, 0) for the far outliers after them."""
    return np.concatenate([np.asarray(cells, np.int64).reshape(-1, 3),
                           np.zeros((far_count, 3), np.int64)])


def channel_priors(prior: ColorPrior, cells: np.ndarray, names: list[str],
                   pool: Executor | None = None) -> dict[str, dict[int, ChannelPrior]]:
    """Run the network on ``cells`` (N, 3): stream -> channel -> :class:`ChannelPrior`;
    with ``pool``, half of the rows run there (:meth:`IntMLP.forward`)."""
    out = prior.net.forward(cells, pool=pool)
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
