"""Byte layout of an integer network payload (spec/FORMAT.md §16.4.3).

    u8 version (1 or 2) | u8 pos_bits | u8 num_freqs | u8 act_bits | u8 layer_count
    per layer: varint out_width | u8 weight_bits | u8 shift
               | version 1: out x in weights (i8 if weight_bits <= 8, i16 if <= 16, else i32;
                 row-major) | out biases (i64)
               | version 2: u8 table | varint + bytes: a residual stream of the out x in
                 weights (row-major) with that frozen table | out biases (svarint)
    per output: svarint lo | svarint hi

Version 2 entropy-codes the weights (a 10-bit weight takes about 7.5 bits instead of 16) and
writes biases as varints (a few bytes instead of 8): on a trained 1,850-anchor scene the
hyperprior network shrinks by about 40%. Encoders write 2 unless a layer breaks the
allocation bound (:func:`~csgs_codec.entropy.residual.coded_value_limit`), then 1; decoders
read both.

Every size is checked against its limit and against the bytes that remain before anything is
allocated; a payload whose network breaks a range or the exactness bound is a FormatError.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.entropy.intnet import (
    BIAS_LIMIT,
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
from csgs_codec.entropy.residual import coded_value_limit, decode_symbols, encode_symbols
from csgs_codec.entropy.table_choice import best_table
from csgs_codec.entropy.tables import gaussian_family
from csgs_codec.errors import FormatError, InputError, ModelError
from csgs_codec.format.primitives import ByteReader, ByteWriter

INTNET_VERSION_RAW = 1
INTNET_VERSION = 2


def weight_dtype(weight_bits: int) -> str:
    """Storage type of weights with ``weight_bits`` signed bits: '<i1', '<i2' or '<i4'."""
    return "<i1" if weight_bits <= 8 else "<i2" if weight_bits <= 16 else "<i4"


def intnet_to_bytes(net: IntMLP, version: int = INTNET_VERSION) -> bytes:
    """Serialize ``net`` (already validated by its constructor) to the payload bytes.

    Args:
        version: 2 (entropy-coded weights, varint biases) or 1 (fixed-width fields).
    """
    if version not in (INTNET_VERSION_RAW, INTNET_VERSION):
        raise InputError(f"unknown network payload version {version}", property="version")
    out = ByteWriter()
    for value in (version, net.pos_bits, net.num_freqs, net.act_bits, len(net.layers)):
        out.fixed("u8", value)
    starts = []  # (payload offset, weight count) of each version-2 layer
    for layer in net.layers:
        out.varint(int(layer.weights.shape[0]))
        out.fixed("u8", layer.weight_bits)
        out.fixed("u8", layer.shift)
        weights = layer.weights.reshape(-1).astype(np.int64)
        if version == INTNET_VERSION_RAW:
            out.array(weights, weight_dtype(layer.weight_bits))
            out.array(layer.biases, "<i8")
            continue
        starts.append((len(out.getvalue()), weights.size))
        write_coded_weights(out, weights)
        for b in layer.biases.tolist():
            out.svarint(b)
    for lo, hi in zip(net.out_lo.tolist(), net.out_hi.tolist()):
        out.svarint(lo)
        out.svarint(hi)
    payload = out.getvalue()
    if any(count > coded_value_limit(len(payload) - start) for start, count in starts):
        return intnet_to_bytes(net, INTNET_VERSION_RAW)
    return payload


def write_coded_weights(out: ByteWriter, weights: np.ndarray) -> None:
    """Append (N,) int64 weights as version 2 codes them: the best frozen table's index (u8)
    and a residual stream (byte string) with that table for every weight."""
    table = best_table(weights)
    out.fixed("u8", table)
    out.byte_string(encode_symbols(weights, np.full(weights.size, table, np.int64)))


def _bounded(reader: ByteReader, field: str, low: int, high: int) -> int:
    start = reader.offset
    value = reader.fixed("u8", field)
    if not low <= value <= high:
        raise reader.error(f"field '{field}' = {value} outside [{low}, {high}]", at=start)
    return value


def read_coded_weights(reader: ByteReader, i: int, count: int, bits: int) -> np.ndarray:
    """Version 2 (also of dense networks): layer ``i``'s ``count`` weights, a table index and a
    residual stream, each weight within ``bits`` signed bits; FormatError otherwise."""
    start = reader.offset
    if count > coded_value_limit(reader.remaining):  # refuse before allocating
        raise reader.error(f"layer {i}: {count} weights exceed the "
                           f"{coded_value_limit(reader.remaining)} allowed with "
                           f"{reader.remaining} payload bytes left", at=start)
    table = _bounded(reader, f"layer {i} table", 0, gaussian_family().count - 1)
    stream = reader.byte_string(f"layer {i} weight stream")
    weights = decode_symbols(stream, np.full(count, table, np.int64), chunk=reader.chunk,
                             base_offset=reader.offset - len(stream))
    limit = 1 << (bits - 1)
    if count and (weights.min() < -limit or weights.max() >= limit):
        raise reader.error(f"layer {i}: a weight is outside {bits} signed bits", at=start)
    return weights


def _varint_biases(reader: ByteReader, i: int, count: int) -> np.ndarray:
    """Version 2: a layer's ``count`` biases as svarints, each below 2^52 in magnitude."""
    if count > reader.remaining:  # each bias takes at least one byte
        raise reader.error(f"truncated: layer {i} biases")
    biases = []
    for _ in range(count):
        start = reader.offset
        b = reader.svarint(f"layer {i} bias")
        if abs(b) >= BIAS_LIMIT:
            raise reader.error(f"layer {i}: bias {b} is not below 2^52 in magnitude",
                               at=start)
        biases.append(b)
    return np.array(biases, dtype=np.int64)


def intnet_from_bytes(data: bytes, *, chunk: str | None = None,
                      base_offset: int = 0) -> IntMLP:
    """Parse a network payload into an :class:`IntMLP`; FormatError on anything invalid."""
    reader = ByteReader(data, base_offset=base_offset, chunk=chunk)
    start = reader.offset
    version = reader.fixed("u8", "version")
    if version not in (INTNET_VERSION_RAW, INTNET_VERSION):
        raise reader.error(f"network payload version {version} is not "
                           f"{INTNET_VERSION_RAW} or {INTNET_VERSION}", at=start)
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
        if version == INTNET_VERSION_RAW:
            weights = reader.array(out_width * width, weight_dtype(bits),
                                   f"layer {i} weights").astype(np.int64)
            biases = reader.array(out_width, "<i8", f"layer {i} biases").astype(np.int64)
        else:
            weights = read_coded_weights(reader, i, out_width * width, bits)
            biases = _varint_biases(reader, i, out_width)
        layers.append(IntLayer(weights.reshape(out_width, width), biases, shift, bits))
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
