"""Byte layout of an integer network payload (spec/drafts/entropy.md §4).

    u8 version (= 1) | u8 pos_bits | u8 num_freqs | u8 act_bits | u8 layer_count
    per layer: varint out_width | u8 weight_bits | u8 shift
               | out x in weights (i8 if weight_bits <= 8, i16 if <= 16, else i32; row-major)
               | out biases (i64)
    per output: svarint lo | svarint hi

Every size is checked against its limit and against the bytes that remain before anything is
allocated; a payload whose network breaks a range or the exactness bound is a FormatError.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.entropy.intnet import (
    MAX_ACT_BITS,
    MAX_FREQS,
    MAX_LAYERS,
    MAX_POS_BITS,
    MAX_SHIFT,
    MAX_WEIGHT_BITS,
    MAX_WIDTH,
    IntLayer,
    IntMLP,
)
from csgs_codec.errors import FormatError, ModelError
from csgs_codec.format.primitives import ByteReader, ByteWriter

INTNET_VERSION = 1


def weight_dtype(weight_bits: int) -> str:
    """Storage type of weights with ``weight_bits`` signed bits: '<i1', '<i2' or '<i4'."""
    return "<i1" if weight_bits <= 8 else "<i2" if weight_bits <= 16 else "<i4"


def intnet_to_bytes(net: IntMLP) -> bytes:
    """Serialize ``net`` (already validated by its constructor) to the payload bytes."""
    out = ByteWriter()
    for value in (INTNET_VERSION, net.pos_bits, net.num_freqs, net.act_bits, len(net.layers)):
        out.fixed("u8", value)
    for layer in net.layers:
        out.varint(int(layer.weights.shape[0]))
        out.fixed("u8", layer.weight_bits)
        out.fixed("u8", layer.shift)
        out.array(layer.weights.reshape(-1), weight_dtype(layer.weight_bits))
        out.array(layer.biases, "<i8")
    for lo, hi in zip(net.out_lo.tolist(), net.out_hi.tolist()):
        out.svarint(lo)
        out.svarint(hi)
    return out.getvalue()


def _bounded(reader: ByteReader, field: str, low: int, high: int) -> int:
    start = reader.offset
    value = reader.fixed("u8", field)
    if not low <= value <= high:
        raise reader.error(f"field '{field}' = {value} outside [{low}, {high}]", at=start)
    return value


def intnet_from_bytes(data: bytes, *, chunk: str | None = None,
                      base_offset: int = 0) -> IntMLP:
    """Parse a network payload into an :class:`IntMLP`; FormatError on anything invalid."""
    reader = ByteReader(data, base_offset=base_offset, chunk=chunk)
    start = reader.offset
    version = reader.fixed("u8", "version")
    if version != INTNET_VERSION:
        raise reader.error(f"network payload version {version} is not {INTNET_VERSION}",
                           at=start)
    pos_bits = _bounded(reader, "pos_bits", 1, MAX_POS_BITS)
    num_freqs = _bounded(reader, "num_freqs", 1, MAX_FREQS)
    act_bits = _bounded(reader, "act_bits", 1, MAX_ACT_BITS)
    count = _bounded(reader, "layer_count", 1, MAX_LAYERS)
    width = 6 * num_freqs
    layers = []
    for i in range(count):
        start = reader.offset
        out_width = reader.varint(f"layer {i} out_width", maximum=MAX_WIDTH)
        if out_width == 0:
            raise reader.error(f"layer {i} out_width is 0", at=start)
        bits = _bounded(reader, f"layer {i} weight_bits", 2, MAX_WEIGHT_BITS)
        shift = _bounded(reader, f"layer {i} shift", 0, MAX_SHIFT)
        weights = reader.array(out_width * width, weight_dtype(bits), f"layer {i} weights")
        biases = reader.array(out_width, "<i8", f"layer {i} biases")
        layers.append(IntLayer(weights.astype(np.int64).reshape(out_width, width),
                               biases.astype(np.int64), shift, bits))
        width = out_width
    ranges = np.array([[reader.svarint("output lo"), reader.svarint("output hi")]
                       for _ in range(width)], dtype=object)
    end = reader.offset
    reader.expect_end("the network payload")
    try:
        lo = np.array([int(v) for v in ranges[:, 0]], dtype=np.int64)
        hi = np.array([int(v) for v in ranges[:, 1]], dtype=np.int64)
    except OverflowError:
        raise FormatError("network output range exceeds 64 bits", chunk=chunk,
                          offset=end) from None
    try:
        return IntMLP(pos_bits, num_freqs, act_bits, tuple(layers), lo, hi)
    except ModelError as err:
        raise FormatError(f"invalid network: {err.message}", chunk=chunk,
                          offset=base_offset) from None
