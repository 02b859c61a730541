"""The anchor codec's entropy-model networks (FORMAT §17.4, §17.5), both directions: AHYP,
the hyperprior over the anchor cells (an integer network payload, §16.4.3), and ACRM, the
CARM networks over the decoded feature groups (a count, then one dense network payload
each). The semantic layer's hyperprior SHYP has AHYP's payload (:func:`hyperprior_payload`)
and is read with :func:`read_position_network` by
:mod:`csgs_codec.chunks.anchor_semantic`.
"""

from __future__ import annotations

from csgs_codec.chunks.stream_list import read_stream_list, stream_list_payload
from csgs_codec.entropy.anchor_attributes import group_bounds, hyper_width
from csgs_codec.entropy.intnet import IntMLP
from csgs_codec.entropy.intnet_bytes import intnet_from_bytes, intnet_to_bytes
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.errors import FormatError

#: Scaling values per anchor.
SCALING_CHANNELS = 6


def color_channels(feat_dim: int, n_offsets: int) -> list[int]:
    """Channel counts of the attribute types AHYP predicts, in its output layout (§17.2):
    features f (F), offsets (3K, channel 3k + d is axis d of offset k), scaling (6)."""
    return [feat_dim, 3 * n_offsets, SCALING_CHANNELS]


def hyperprior_payload(net: IntMLP) -> bytes:
    """The AHYP (or SHYP) payload of hyperprior ``net``: its integer network bytes."""
    return intnet_to_bytes(net)


def read_position_network(data: bytes, offset: int, chunk: str, pos_bits: int) -> IntMLP:
    """The hyperprior of a ``chunk`` payload (AHYP or SHYP) at absolute byte ``offset``,
    which must take cells of ``pos_bits`` bits per axis (``max(grid_bits, 1)``).

    Raises:
        FormatError: naming ``chunk`` and the byte offset.
    """
    net = intnet_from_bytes(data, chunk=chunk, base_offset=offset)
    if net.pos_bits != pos_bits:
        raise FormatError(f"network pos_bits {net.pos_bits} differs from the grid's "
                          f"{pos_bits}", chunk=chunk, offset=offset)
    return net


def check_outputs(net: IntMLP, channels: list[int], chunk: str, offset: int) -> None:
    """FormatError naming ``chunk`` (at absolute byte ``offset``, its payload's) unless
    hyperprior ``net`` has the outputs of attribute types of ``channels`` channels (2C + 1
    each: means, scales, a step)."""
    if net.out_width != hyper_width(channels):
        raise FormatError(f"hyperprior has {net.out_width} outputs, the layout needs "
                          f"{hyper_width(channels)}", chunk=chunk, offset=offset)


def read_hyperprior(container, pos_bits: int, feat_dim: int, n_offsets: int) -> IntMLP:
    """The AHYP network of ``container``: cells of ``pos_bits`` bits per axis in, the
    2F + 6K + 15 outputs of :func:`color_channels` out.

    Raises:
        FormatError: naming AHYP and the byte offset (missing, malformed, another grid or
            another output layout).
    """
    data, offset = container.single_payload("AHYP")
    net = read_position_network(data, offset, "AHYP", pos_bits)
    check_outputs(net, color_channels(feat_dim, n_offsets), "AHYP", offset)
    return net


def carm_payload(networks: list[IntDenseMLP]) -> bytes:
    """The ACRM payload of the G - 1 CARM ``networks`` (none when G = 1): their count,
    then each network's dense payload, length-prefixed."""
    return stream_list_payload([net.to_bytes() for net in networks])


def read_carm(container, feat_dim: int, groups: int) -> list[IntDenseMLP]:
    """The ``groups`` - 1 CARM networks of ``container``'s ACRM: network g - 1 takes the
    decoded grid values of the g F // G channels before group g of the F = ``feat_dim``
    feature channels and returns 2 C_g integers (C_g the channels of group g).

    Raises:
        FormatError: naming ACRM and the byte offset (another count, a malformed network,
            or one whose widths do not fit its group).
    """
    data, offset = container.single_payload("ACRM")
    networks = []
    bounds = group_bounds(feat_dim, groups)
    for g, (payload, at) in enumerate(read_stream_list(data, offset, "ACRM", groups - 1), 1):
        net = IntDenseMLP.from_bytes(payload, chunk="ACRM", base_offset=at)
        lo, hi = bounds[g]
        if net.in_width != lo or net.out_width != 2 * (hi - lo):
            raise FormatError(f"CARM network {g - 1} ({net.in_width} -> {net.out_width}) "
                              f"does not fit {lo} decoded channels and a group of {hi - lo}",
                              chunk="ACRM", offset=at)
        networks.append(net)
    return networks
