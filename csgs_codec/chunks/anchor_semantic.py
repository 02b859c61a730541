"""The anchor codec's semantic features (FORMAT §17.11), both directions: SHYP, the semantic
hyperprior (an integer network payload over the anchor cells with 2S + 1 outputs, written by
:func:`csgs_codec.chunks.anchor_networks.hyperprior_payload`), and ASEM: the S channel names
(§12.16), then one length-prefixed residual stream of the M x S semantic values on the grid
of 2^-12 value units, anchor-major. SHYP and ASEM are both present or both absent. Anchor
labels are SEML or SEMR (:mod:`csgs_codec.chunks.semantic`).
"""

from __future__ import annotations

import numpy as np

from csgs_codec.chunks.anchor_networks import check_outputs, read_position_network
from csgs_codec.chunks.anchor_streams import grid_floats
from csgs_codec.chunks.semantic_names import names_from_bytes, names_to_bytes
from csgs_codec.entropy.anchor_attributes import (
    FRAC_BITS,
    EntropyParams,
    decode_block,
    encode_block,
    hyper_params,
)
from csgs_codec.entropy.residual import to_grid
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Most semantic channels a decoder accepts (ASEM's channel_count is 0..4096).
MAX_ANCHOR_SEMANTIC_CHANNELS = 4096


def semantic_stream(semantic: np.ndarray, params: EntropyParams) -> tuple[bytes, np.ndarray]:
    """(ASEM's residual stream, decoded (M, S) float32 values) of the semantic features
    ``semantic`` (M, S), value units, coded with the semantic hyperprior's ``params``."""
    m, width = semantic.shape
    stream, decoded = encode_block(to_grid(semantic.reshape(-1), FRAC_BITS).reshape(m, width),
                                   params)
    return stream, grid_floats(decoded)


def anchor_semantic_payload(names: tuple[str, ...], stream: bytes) -> bytes:
    """The ASEM payload: the channel ``names``, then :func:`semantic_stream`'s ``stream``
    length-prefixed."""
    out = ByteWriter()
    names_to_bytes(out, names)
    out.byte_string(stream)
    return out.getvalue()


def read_anchor_semantic(container, cells: np.ndarray,
                         pos_bits: int) -> tuple[tuple[str, ...], np.ndarray] | None:
    """(channel names, (M, S) float32 semantic features) of ``container``'s SHYP and ASEM,
    for the anchors of ``cells`` (M, 3) int on a grid of ``pos_bits`` bits per axis; None
    when the container holds neither.

    Raises:
        FormatError: naming the chunk and byte offset (only one of the two present, a
            malformed payload, a hyperprior that does not fit S channels, a value beyond
            float32).
    """
    present = {e.type for e in container.toc}
    if ("ASEM" in present) != ("SHYP" in present):
        raise FormatError("ASEM and SHYP must both be present or both absent",
                          chunk="ASEM" if "ASEM" not in present else "SHYP")
    if "ASEM" not in present:
        return None
    data, net_offset = container.single_payload("SHYP")
    hyper = read_position_network(data, net_offset, "SHYP", pos_bits)
    data, offset = container.single_payload("ASEM")
    r = ByteReader(data, base_offset=offset, chunk="ASEM")
    names = names_from_bytes(r, MAX_ANCHOR_SEMANTIC_CHANNELS)
    stream = r.byte_string("stream")
    r.expect_end("the semantic payload")
    check_outputs(hyper, [len(names)], "SHYP", net_offset)
    (params,) = hyper_params(hyper, cells, [len(names)])
    values = grid_floats(decode_block(stream, params, chunk="ASEM",
                                      base_offset=r.offset - len(stream)))
    if not np.all(np.isfinite(values)):
        raise FormatError("decoded semantic features overflow float32", chunk="ASEM")
    return names, values
