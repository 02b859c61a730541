"""Integer MLP over plain integer inputs (numpy only): :class:`IntMLP`'s arithmetic without
the positional embedding, for networks conditioned on decoded values (e.g. the CARM).

    x' = clip(x >> input_shift, -(2^input_bits - 1), 2^input_bits - 1)   # (N, D) int64
    for each layer: y = (W x' + b + 2^(s-1)) >> s                          # rounds half up
                    hidden: x' = clip(y, 0, 2^act_bits - 1);  last: clip(y, lo, hi)

The layers are :class:`~csgs_codec.entropy.intnet.IntLayer` with the same ranges and the same
exactness bound as :class:`~csgs_codec.entropy.intnet.IntMLP` (every worst-case accumulator
``sum |W| X + |b| + 2^(s-1) <= 2^53``, X the largest input magnitude), so the float64 BLAS
path and the int64 reference path agree bit for bit on every machine and thread count.

Payload (spec/FORMAT.md §17.5):

    u8 version (2; 1 still reads) | varint in_width | u8 input_shift | u8 input_bits
    | u8 act_bits | u8 layer_count
    per layer: varint out_width | u8 weight_bits | u8 shift
               | weights: version 2: u8 table + residual stream (row-major);
                          version 1: out x in i8 / i16 / i32 by weight_bits
               | out biases (svarint each)
    per output: svarint lo | svarint hi

A version-2 layer holds at most 4 weights per payload byte left + 65,536
(:func:`~csgs_codec.entropy.residual.coded_value_limit`); an encoder whose network would
break that writes version 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.entropy.intnet import (
    BIAS_LIMIT,
    MAX_ACT_BITS,
    MAX_LAYERS,
    MAX_SHIFT,
    MAX_WEIGHT_BITS,
    MAX_WIDTH,
    OUTPUT_LIMIT,
    IntLayer,
    _frozen,
    _frozen_layer,
    layers_float64,
    layers_int64,
    validate_layers,
    worst_case_sums,
)
from csgs_codec.entropy.intnet_bytes import read_coded_weights, weight_dtype, write_coded_weights
from csgs_codec.entropy.residual import coded_value_limit
from csgs_codec.errors import FormatError, InputError, ModelError
from csgs_codec.format.primitives import ByteReader, ByteWriter

DENSE_VERSION = 2
DENSE_VERSION_RAW = 1
#: Largest input_bits (inputs are clipped to +-(2^input_bits - 1) after the shift).
MAX_INPUT_BITS = 30
#: Largest input_shift.
MAX_INPUT_SHIFT = 62
_ROWS_PER_BLOCK = 4096


@dataclass(frozen=True, eq=False)
class IntDenseMLP:
    """An exact integer network over (N, D) integer inputs.

    Attributes:
        in_width: D, 1..4096.
        input_shift: inputs are floor-shifted right by this many bits first, 0..62.
        input_bits: shifted inputs are clipped to [-(2^b - 1), 2^b - 1], 1..30.
        act_bits: hidden activations are clamped to [0, 2^act_bits - 1], 1..30.
        layers: 1..16 :class:`IntLayer`; the first takes D inputs.
        out_lo, out_hi: (O,) int64 inclusive clamp of each output.

    Raises ModelError on construction when a range or the exactness bound is violated.
    """

    in_width: int
    input_shift: int
    input_bits: int
    act_bits: int
    layers: tuple[IntLayer, ...]
    out_lo: np.ndarray
    out_hi: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "layers", tuple(_frozen_layer(x) for x in self.layers))
        object.__setattr__(self, "out_lo", _frozen(self.out_lo))
        object.__setattr__(self, "out_hi", _frozen(self.out_hi))
        validate_dense(self)

    @property
    def out_width(self) -> int:
        """Number of outputs O."""
        return int(self.layers[-1].weights.shape[0])

    def input_bounds(self) -> list[int]:
        """Largest input magnitude of each layer."""
        hidden = (1 << self.act_bits) - 1
        return [(1 << self.input_bits) - 1] + [hidden] * (len(self.layers) - 1)

    def worst_case_sums(self) -> list[int]:
        """Per layer, max over outputs of sum |W| * X + |b| + 2^(s-1) (Python ints)."""
        return worst_case_sums(self.layers, self.input_bounds())

    def prepare(self, inputs: np.ndarray) -> np.ndarray:
        """The first layer's input: (N, D) int -> (N, D) int64 shifted and clipped."""
        x = np.asarray(inputs)
        if x.ndim != 2 or x.shape[1] != self.in_width:
            raise InputError(f"inputs must have shape (N, {self.in_width}), got {x.shape}")
        if x.size and not np.issubdtype(x.dtype, np.integer):
            raise InputError(f"inputs must be integers, got {x.dtype}")
        top = (1 << self.input_bits) - 1
        return np.clip(x.astype(np.int64) >> self.input_shift, -top, top)

    def forward(self, inputs: np.ndarray, path: str = "float64") -> np.ndarray:
        """Evaluate: (N, D) integers -> (N, O) int64; "float64" (BLAS) and "int64" agree."""
        if path not in ("float64", "int64"):
            raise InputError(f"unknown inference path {path!r}")
        x = self.prepare(inputs)
        out = np.empty((x.shape[0], self.out_width), dtype=np.int64)
        for start in range(0, x.shape[0], _ROWS_PER_BLOCK):
            block = x[start:start + _ROWS_PER_BLOCK]
            rows = slice(start, start + block.shape[0])
            out[rows] = (self._float64(block.astype(np.float64)) if path == "float64"
                         else self._int64(block))
        return out

    def _int64(self, h: np.ndarray) -> np.ndarray:
        return layers_int64(self.layers, h, self.act_bits, self.out_lo, self.out_hi)

    def _float64(self, h: np.ndarray) -> np.ndarray:
        return layers_float64(self.layers, h, self.act_bits, self.out_lo, self.out_hi)

    def to_bytes(self, version: int = DENSE_VERSION) -> bytes:
        """The network payload (module docstring) in ``version`` 2 (coded weights) or 1 (fixed
        width); version 2 falls back to 1 when a layer has more weights than it may hold."""
        if version not in (DENSE_VERSION_RAW, DENSE_VERSION):
            raise InputError(f"unknown dense network version {version}", property="version")
        out = ByteWriter()
        out.fixed("u8", version)
        out.varint(self.in_width)
        for value in (self.input_shift, self.input_bits, self.act_bits, len(self.layers)):
            out.fixed("u8", value)
        starts = []  # (payload offset, weight count) of each version-2 layer
        for layer in self.layers:
            out.varint(int(layer.weights.shape[0]))
            out.fixed("u8", layer.weight_bits)
            out.fixed("u8", layer.shift)
            weights = layer.weights.reshape(-1).astype(np.int64)
            if version == DENSE_VERSION_RAW:
                out.array(weights, weight_dtype(layer.weight_bits))
            else:
                starts.append((len(out.getvalue()), weights.size))
                write_coded_weights(out, weights)
            for b in layer.biases.tolist():
                out.svarint(b)
        for lo, hi in zip(self.out_lo.tolist(), self.out_hi.tolist()):
            out.svarint(lo)
            out.svarint(hi)
        payload = out.getvalue()
        if any(count > coded_value_limit(len(payload) - start) for start, count in starts):
            return self.to_bytes(DENSE_VERSION_RAW)
        return payload

    @classmethod
    def from_bytes(cls, data: bytes, *, chunk: str | None = None,
                   base_offset: int = 0) -> IntDenseMLP:
        """Parse a payload; FormatError (with offset) on anything malformed or out of range."""
        return read_dense(ByteReader(data, base_offset=base_offset, chunk=chunk))


def _bounded(reader: ByteReader, field: str, low: int, high: int) -> int:
    start = reader.offset
    value = reader.fixed("u8", field)
    if not low <= value <= high:
        raise reader.error(f"field '{field}' = {value} outside [{low}, {high}]", at=start)
    return value


def _signed(reader: ByteReader, field: str, limit: int) -> int:
    start = reader.offset
    value = reader.svarint(field)
    if not -limit <= value <= limit:
        raise reader.error(f"field '{field}' = {value} outside +-2^{limit.bit_length() - 1}",
                           at=start)
    return value


def read_dense(reader: ByteReader) -> IntDenseMLP:
    """Read one network payload that fills what remains of ``reader``."""
    start = reader.offset
    version = reader.fixed("u8", "version")
    if version not in (DENSE_VERSION_RAW, DENSE_VERSION):
        raise reader.error(f"dense network version {version} is not {DENSE_VERSION_RAW} or "
                           f"{DENSE_VERSION}", at=start)
    in_width = reader.varint("in_width", maximum=MAX_WIDTH)
    if in_width == 0:
        raise reader.error("in_width is 0")
    input_shift = _bounded(reader, "input_shift", 0, MAX_INPUT_SHIFT)
    input_bits = _bounded(reader, "input_bits", 1, MAX_INPUT_BITS)
    act_bits = _bounded(reader, "act_bits", 1, MAX_ACT_BITS)
    count = _bounded(reader, "layer_count", 1, MAX_LAYERS)
    width, layers = in_width, []
    for i in range(count):
        out_width = reader.varint(f"layer {i} out_width", maximum=MAX_WIDTH)
        if out_width == 0:
            raise reader.error(f"layer {i} out_width is 0")
        bits = _bounded(reader, f"layer {i} weight_bits", 2, MAX_WEIGHT_BITS)
        shift = _bounded(reader, f"layer {i} shift", 0, MAX_SHIFT)
        if version == DENSE_VERSION_RAW:
            weights = reader.array(out_width * width, weight_dtype(bits), f"layer {i} weights")
        else:
            weights = read_coded_weights(reader, i, out_width * width, bits)
        if out_width > reader.remaining:  # each bias takes at least one byte
            raise reader.error(f"truncated: layer {i} biases")
        biases = [_signed(reader, f"layer {i} bias", BIAS_LIMIT) for _ in range(out_width)]
        layers.append(IntLayer(weights.astype(np.int64).reshape(out_width, width),
                               np.array(biases, dtype=np.int64), shift, bits))
        width = out_width
    if 2 * width > reader.remaining:
        raise reader.error("truncated: output ranges")
    ranges = [(_signed(reader, "output lo", OUTPUT_LIMIT),
               _signed(reader, "output hi", OUTPUT_LIMIT)) for _ in range(width)]
    lo, hi = [r[0] for r in ranges], [r[1] for r in ranges]
    reader.expect_end("the dense network payload")
    try:
        return IntDenseMLP(in_width, input_shift, input_bits, act_bits, tuple(layers),
                           np.array(lo, dtype=np.int64), np.array(hi, dtype=np.int64))
    except ModelError as err:
        raise FormatError(f"invalid dense network: {err.message}", chunk=reader.chunk,
                          offset=start) from None


def validate_dense(net: IntDenseMLP) -> None:
    """Check every range of :class:`IntDenseMLP` and the exactness bound; ModelError if not."""
    if not 1 <= net.in_width <= MAX_WIDTH:
        raise ModelError(f"in_width {net.in_width} outside [1, {MAX_WIDTH}]")
    if not 0 <= net.input_shift <= MAX_INPUT_SHIFT:
        raise ModelError(f"input_shift {net.input_shift} outside [0, {MAX_INPUT_SHIFT}]")
    if not 1 <= net.input_bits <= MAX_INPUT_BITS:
        raise ModelError(f"input_bits {net.input_bits} outside [1, {MAX_INPUT_BITS}]")
    if not 1 <= net.act_bits <= MAX_ACT_BITS:
        raise ModelError(f"act_bits {net.act_bits} outside [1, {MAX_ACT_BITS}]")
    if not 1 <= len(net.layers) <= MAX_LAYERS:
        raise ModelError(f"{len(net.layers)} layers outside [1, {MAX_LAYERS}]")
    validate_layers(net.layers, net.in_width, net.out_lo, net.out_hi, net.input_bounds())
