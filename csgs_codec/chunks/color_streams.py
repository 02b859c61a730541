"""The color layer's stream chunks (FORMAT §12.8-12.14), both directions: SHDC, SHBA-SHBC,
OPAC and SCAL each hold one float stream (:mod:`csgs_codec.attributes.float_stream`); ROTN holds
the dropped-component categorical stream, then the rotations' float stream.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.attributes.channel_coders import TABLE_CONSTANT, Coding
from csgs_codec.attributes.derived_steps import SCORE_FEATURES
from csgs_codec.attributes.float_stream import (
    ChannelPrior,
    StreamPlan,
    read_float_stream,
    write_planned_stream,
)
from csgs_codec.attributes.sh_colour_transform import band_colours
from csgs_codec.chunks.checks import check_finite
from csgs_codec.entropy.categorical import decode_categorical, encode_categorical
from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Color stream name -> its chunk type, and back; channels per stream.
STREAM_CHUNKS = {"dc": "SHDC", "rest1": "SHBA", "rest2": "SHBB", "rest3": "SHBC",
                 "opacity": "OPAC", "scale": "SCAL", "rot": "ROTN"}
CHUNK_STREAMS = {v: k for k, v in STREAM_CHUNKS.items()}
STREAM_CHANNELS = {"dc": 3, "rest1": 9, "rest2": 15, "rest3": 21, "opacity": 1, "scale": 3,
                   "rot": 3}


def color_stream_payload(name: str, plan: StreamPlan, prior_channels=None,
                         rot_axis: np.ndarray | None = None) -> bytes:
    """The payload of color stream ``name`` ("dc", "rest1".."rest3", "opacity", "scale",
    "rot"): ``plan``'s float stream with the hyperprior's ``prior_channels`` for it (None:
    none), after the (N,) dropped-component indices ``rot_axis`` for "rot"."""
    out = ByteWriter()
    if name == "rot":
        out.byte_string(encode_categorical(rot_axis, 4))
    write_planned_stream(out, plan, prior_channels)
    return out.getvalue()


def read_color_stream(container, count: int, name: str,
                      priors: dict[int, ChannelPrior] | None = None, log_scales=None,
                      opacity=None, colour_transform: tuple[tuple[int, ...], int] | None = None
                      ) -> tuple[np.ndarray, np.ndarray | None]:
    """(values (count, C) float32, dropped-component index per Gaussian for "rot" else None)
    of color stream ``name`` in ``container``; ``priors`` are the hyperprior's for its
    modelled channels,
    ``log_scales`` and ``opacity`` (rotations only) return the decoded scales and opacity
    logits scored steps derive from, and ``colour_transform`` (SH bands) is the SHXF
    record (transform per band, its offset) whose inverse this band gets.

    Raises:
        FormatError: naming the chunk and byte offset.
    """
    code = STREAM_CHUNKS[name]
    data, offset = container.single_payload(code)
    r = ByteReader(data, base_offset=offset, chunk=code)
    rot_axis = None
    if name == "rot":
        axis_stream = r.byte_string("axis_stream")
        rot_axis = decode_categorical(axis_stream, count, chunk=code,
                                      base_offset=r.offset - len(axis_stream))
        if rot_axis.size and rot_axis.max() > 3:
            raise r.error("dropped-component index above 3")
    values = read_float_stream(r, count, STREAM_CHANNELS[name], priors,
                               log_scales, opacity)
    r.expect_end(f"the {name} stream")
    check_finite(values, code)
    if colour_transform is not None:  # in this stream's job, beside the other streams
        transforms, record_offset = colour_transform
        values = band_colours(values, int(name[len("rest"):]), transforms, record_offset)
    return values, rot_axis


def rotation_step_summary(data: bytes, offset: int) -> dict:
    """How a ROTN payload (at absolute byte ``offset``) sets its coded channels' steps, from
    its first coded channel record: {"coding" (the channel's ``coding`` name), "name"
    ("uniform" or "footprint"), "classes"} (``csgs info``; the encoder gives every channel of
    a stream the same kind).

    Raises:
        FormatError: the record is cut off or malformed.
    """
    r = ByteReader(data, offset, chunk="ROTN")
    coding = rotation_class_table(r)
    if not coding.scored:
        return {"coding": coding.name, "name": "uniform", "classes": 1}
    for _ in range(2 * SCORE_FEATURES):
        r.fixed("f32", "score_weight")
    k_u = r.fixed("u8", "bin_count_u")
    for _ in range(k_u - 1):
        r.fixed("f32", "threshold_u")
    return {"coding": coding.name, "name": "footprint",
            "classes": k_u * r.fixed("u8", "bin_count_v")}


def rotation_coding_offset(payload: bytes) -> int:
    """Offset in a ROTN ``payload`` of its first coded channel's ``coding`` byte, or -1 when
    every channel is a constant. For inspection (tests, vector damage), not for decoding."""
    r = ByteReader(payload, chunk="ROTN")
    r.byte_string("axis_stream")
    r.varint("count")
    channels = r.fixed("u8", "channel_count")
    r.fixed("u8", "frac_bits")
    for c in range(channels):
        at = r.offset
        if Coding.read(r, c).table != TABLE_CONSTANT:
            return at
        r.fixed("f32", "constant_value")
    return -1


def rotation_class_table(r: ByteReader) -> Coding:
    """Walk a ROTN payload (``r`` at its start) to its first channel that is not a constant;
    returns that channel's :class:`Coding`, with ``r`` just past its step index when its
    steps are scored (where its score table starts), else just past the ``coding`` byte (a
    constant coding when every channel is a constant). For inspection (``csgs info``, tests,
    vector damage), not for decoding."""
    r.byte_string("axis_stream")
    r.varint("count")
    channels = r.fixed("u8", "channel_count")
    r.fixed("u8", "frac_bits")
    coding = Coding(TABLE_CONSTANT)
    for c in range(channels):
        coding = Coding.read(r, c)
        if coding.table != TABLE_CONSTANT:
            break
        r.fixed("f32", "constant_value")
    if coding.scored:
        r.svarint("mean")
        r.fixed("u8", "step_index")
    return coding
