"""Integer MLP inference (numpy only): exact, identical on every machine and thread count.

A network maps integer positions (N, 3) in [0, 2^pos_bits) to integer outputs (N, O):

    e = positional_embedding(x)                       # (N, 6L) in [-2^14, 2^14]
    for each layer: y = (W e + b + 2^(s-1)) >> s      # floor shift: rounds half up
                    hidden: e = clip(y, 0, 2^act_bits - 1);  last: clip(y, lo, hi)

Two paths compute it: int64 (the reference) and float64 BLAS. The float64 path is exact
because every layer satisfies ``sum_j |W_oj| * X + |b_o| + 2^(s-1) <= 2^53`` (X the largest
input magnitude): every product and every partial sum in any summation order is then an
integer of magnitude at most 2^53, which float64 holds exactly (also with FMA), and the
shift is an exact multiplication by 2^-s followed by floor. :class:`IntMLP` refuses a
network that breaks the bound (ModelError), so both paths always agree.
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from csgs_codec.entropy.tables import SINE_AMPLITUDE_BITS, SINE_INDEX_BITS, sine_table
from csgs_codec.errors import InputError, ModelError

EXACT_LIMIT = 1 << 53
MAX_POS_BITS = 32
MAX_FREQS = 16
MAX_ACT_BITS = 30
MAX_LAYERS = 16
MAX_WIDTH = 4096
MAX_WEIGHT_BITS = 24
MAX_SHIFT = 62
BIAS_LIMIT = 1 << 52
OUTPUT_LIMIT = 1 << 53
EMBED_LIMIT = 1 << SINE_AMPLITUDE_BITS
#: Rows evaluated per block: 2,048, or a sixteenth of the rows for large inputs (fewer calls
#: of small matrix products), at most 16,384 and at most what keeps the block's float64 work
#: arrays within _BLOCK_VALUES values (8 MiB) whatever widths a network declares (at least
#: 64 rows). Work memory thus stays a small share of the input's own arrays.
_BASE_BLOCK_ROWS = 2048
_BLOCK_VALUES = 1 << 20
_MAX_BLOCK_ROWS = 16384
_MIN_BLOCK_ROWS = 64


def positional_embedding(positions: np.ndarray, pos_bits: int, num_freqs: int) -> np.ndarray:
    """Integer sine/cosine features of integer positions.

    Args:
        positions: (N, 3) integers in [0, 2^pos_bits).
        pos_bits: bits per coordinate, 1..32.
        num_freqs: L, 1..16 octaves.

    Returns:
        (N, 6L) int64: feature 6l + 2d is T[i], feature 6l + 2d + 1 is T[(i + 256) mod 1024]
        with i = floor(x_d * 2^(l + 10) / 2^pos_bits) mod 1024 and T the frozen sine table
        (round(2^14 sin(2 pi i / 1024))).
    """
    return _embed(_checked_positions(positions, pos_bits), pos_bits, num_freqs,
                  _sine_pairs("int64"))


def _checked_positions(positions: np.ndarray, pos_bits: int) -> np.ndarray:
    """(N, 3) integer positions in [0, 2^pos_bits) as int64, else InputError."""
    x = np.asarray(positions)
    if x.ndim != 2 or x.shape[1] != 3:
        raise InputError(f"positions must have shape (N, 3), got {x.shape}")
    if x.size and not np.issubdtype(x.dtype, np.integer):
        raise InputError(f"positions must be integers, got {x.dtype}")
    x = x.astype(np.int64)
    if x.size and (x.min() < 0 or x.max() >= (1 << pos_bits)):
        raise InputError(f"positions must lie in [0, 2^{pos_bits})")
    return x


def _embed(x: np.ndarray, pos_bits: int, num_freqs: int, pairs: np.ndarray) -> np.ndarray:
    """The embedding of validated (N, 3) positions; ``pairs`` is :func:`_sine_pairs`."""
    mask = np.uint32((1 << SINE_INDEX_BITS) - 1)
    x32 = x.astype(np.uint32)
    # ((x << (l + 10)) >> B) mod 1024 as a right shift by B - l - 10 when that is >= 0, else
    # a left shift: only the low 10 bits are kept, so 32-bit wrap-around cannot change them.
    phase = np.empty((x.shape[0], num_freqs, 3), dtype=np.uint32)
    for level in range(num_freqs):
        down = pos_bits - level - SINE_INDEX_BITS
        moved = x32 >> np.uint32(down) if down >= 0 else x32 << np.uint32(-down)
        np.bitwise_and(moved, mask, out=phase[:, level, :])
    return pairs[phase].reshape(x.shape[0], 6 * num_freqs)


@lru_cache(maxsize=2)
def _sine_pairs(dtype: str) -> np.ndarray:
    """(1024, 2) table of (T[i], T[(i + 256) mod 1024]) as int64 or float64 (exact)."""
    table = sine_table()
    quarter = 1 << (SINE_INDEX_BITS - 2)
    pairs = np.stack((table, np.roll(table, -quarter)), axis=1).astype(dtype)
    pairs.setflags(write=False)
    return pairs


@dataclass(frozen=True, eq=False)
class IntLayer:
    """One integer affine layer.

    Attributes:
        weights: (out, in) int64, each in [-2^(weight_bits-1), 2^(weight_bits-1) - 1].
        biases: (out,) int64, |b| < 2^52.
        shift: s in [0, 62]; the accumulator is rounded by (acc + 2^(s-1)) >> s.
        weight_bits: signed bit width of the weights, 2..24.
    """

    weights: np.ndarray
    biases: np.ndarray
    shift: int
    weight_bits: int


@dataclass(frozen=True, eq=False)
class IntMLP:
    """An integer network over the positional embedding of integer positions.

    Attributes:
        pos_bits: positions are in [0, 2^pos_bits) per axis, 1..32.
        num_freqs: embedding octaves L (input width 6L), 1..16.
        act_bits: hidden activations are clamped to [0, 2^act_bits - 1], 1..30.
        layers: 1..16 :class:`IntLayer`; widths chain, the first takes 6L inputs.
        out_lo, out_hi: (O,) int64 inclusive clamp of each output (the index ranges).

    Raises ModelError on construction when any range is violated or a layer could leave
    the exact float64 range (see the module docstring).
    """

    pos_bits: int
    num_freqs: int
    act_bits: int
    layers: tuple[IntLayer, ...]
    out_lo: np.ndarray
    out_hi: np.ndarray

    def __post_init__(self) -> None:
        layers = tuple(self.layers)
        object.__setattr__(self, "layers", tuple(_frozen_layer(layer) for layer in layers))
        object.__setattr__(self, "out_lo", _frozen(self.out_lo))
        object.__setattr__(self, "out_hi", _frozen(self.out_hi))
        validate(self)

    @property
    def in_width(self) -> int:
        """Input width 6L."""
        return 6 * self.num_freqs

    @property
    def out_width(self) -> int:
        """Number of outputs O."""
        return int(self.layers[-1].weights.shape[0])

    def input_bounds(self) -> list[int]:
        """Largest input magnitude of each layer: 2^14 for the first, 2^act_bits - 1 after."""
        hidden = (1 << self.act_bits) - 1
        return [EMBED_LIMIT] + [hidden] * (len(self.layers) - 1)

    def worst_case_sums(self) -> list[int]:
        """Per layer, max over outputs of sum |W| * X + |b| + 2^(s-1) (Python ints)."""
        return worst_case_sums(self.layers, self.input_bounds())

    def embed(self, positions: np.ndarray) -> np.ndarray:
        """(N, 3) integer positions -> (N, 6L) int64 embedding."""
        return positional_embedding(positions, self.pos_bits, self.num_freqs)

    def forward(self, positions: np.ndarray, path: str = "float64",
                pool: Executor | None = None) -> np.ndarray:
        """Evaluate the network: (N, 3) integer positions -> (N, O) int64 outputs.

        ``path`` is "float64" (BLAS, fast) or "int64" (reference); both give identical results.
        With ``pool``, the second half of the rows is evaluated there while the calling
        thread does the first (rows are independent, so the outputs are the same).
        """
        if path not in ("float64", "int64"):
            raise InputError(f"unknown inference path {path!r}")
        x = _checked_positions(positions, self.pos_bits)
        out = np.empty((x.shape[0], self.out_width), dtype=np.int64)
        pairs = _sine_pairs(path)
        widths = sum(layer.weights.shape[0] for layer in self.layers) + self.in_width
        n = x.shape[0]
        block = min(max(_BASE_BLOCK_ROWS, n // 16), _MAX_BLOCK_ROWS,
                    max(_MIN_BLOCK_ROWS, _BLOCK_VALUES // widths), max(n, 1))

        def rows_from(first: int, end: int) -> None:
            # Work arrays reused by every block of one task (never shared between threads).
            buffers = [np.empty((block, layer.weights.shape[0])) for layer in self.layers]
            for start in range(first, end, block):
                emb = _embed(x[start:min(start + block, end)], self.pos_bits, self.num_freqs,
                             pairs)
                rows = slice(start, start + emb.shape[0])
                if path == "float64":
                    out[rows] = self._forward_float64(emb, buffers)
                else:
                    out[rows] = self._forward_int64(emb)

        half = -(-(n // 2) // block) * block  # the first half, in whole blocks
        if pool is None or n < 2 * block:
            rows_from(0, n)
        else:
            second = pool.submit(rows_from, half, n)
            rows_from(0, half)
            second.result()
        return out

    def _forward_int64(self, h: np.ndarray) -> np.ndarray:
        return layers_int64(self.layers, h, self.act_bits, self.out_lo, self.out_hi)

    def _forward_float64(self, h: np.ndarray, buffers: list[np.ndarray]) -> np.ndarray:
        return layers_float64(self.layers, h, self.act_bits, self.out_lo, self.out_hi, buffers)


def _frozen(a) -> np.ndarray:
    arr = np.asarray(a)
    if arr.size and not (np.issubdtype(arr.dtype, np.integer) or arr.dtype == object
                         or np.all(np.mod(arr, 1) == 0)):
        raise ModelError("network weights, biases and ranges must be integers")
    try:
        out = np.array(a, dtype=np.int64, copy=True)
    except (OverflowError, ValueError, TypeError) as exc:
        raise ModelError(f"network parameter does not fit int64: {exc}") from None
    out.setflags(write=False)
    return out


def _frozen_layer(layer: IntLayer) -> IntLayer:
    return IntLayer(_frozen(layer.weights), _frozen(layer.biases), int(layer.shift),
                    int(layer.weight_bits))


def _float_params(layer: IntLayer):
    """(W^T * 2^-s, (b + 2^(s-1)) * 2^-s) as float64 — exact (powers of two, no underflow).

    Computed once per layer and kept on the (immutable) layer object.
    """
    params = layer.__dict__.get("_float64_params")
    if params is None:
        half = (1 << (layer.shift - 1)) if layer.shift else 0
        w = np.ldexp(np.ascontiguousarray(layer.weights.T, dtype=np.float64), -layer.shift)
        offset = np.ldexp((layer.biases + half).astype(np.float64), -layer.shift)
        params = (w, offset)
        object.__setattr__(layer, "_float64_params", params)
    return params


def _fail(message: str, **context) -> ModelError:
    return ModelError(message, **context)


def validate(net: IntMLP) -> None:
    """Check every range of :class:`IntMLP` and the exactness bound; ModelError if broken."""
    if not 1 <= net.pos_bits <= MAX_POS_BITS:
        raise _fail(f"pos_bits {net.pos_bits} outside [1, {MAX_POS_BITS}]")
    if not 1 <= net.num_freqs <= MAX_FREQS:
        raise _fail(f"num_freqs {net.num_freqs} outside [1, {MAX_FREQS}]")
    if not 1 <= net.act_bits <= MAX_ACT_BITS:
        raise _fail(f"act_bits {net.act_bits} outside [1, {MAX_ACT_BITS}]")
    if not 1 <= len(net.layers) <= MAX_LAYERS:
        raise _fail(f"{len(net.layers)} layers outside [1, {MAX_LAYERS}]")
    validate_layers(net.layers, net.in_width, net.out_lo, net.out_hi, net.input_bounds())


def worst_case_sums(layers, input_bounds: list[int]) -> list[int]:
    """Per layer, max over outputs of sum |W| * X + |b| + 2^(s-1) (Python ints), X the
    layer's largest input magnitude."""
    sums = []
    for layer, bound in zip(layers, input_bounds):
        # Row sums fit int64 (|w| < 2^23, width <= 4096); the products use Python ints.
        abs_rows = np.abs(layer.weights).sum(axis=1).tolist()
        half = (1 << (layer.shift - 1)) if layer.shift else 0
        sums.append(max(r * bound + abs(int(b)) + half
                        for r, b in zip(abs_rows, layer.biases.tolist())))
    return sums


def validate_layers(layers, in_width: int, out_lo: np.ndarray, out_hi: np.ndarray,
                    input_bounds: list[int]) -> None:
    """Check the layers of an integer network (shapes, bit widths, shifts, output ranges)
    and the exactness bound (every worst-case accumulator <= 2^53); ModelError if broken.
    Shared by every integer network type, so they all obey the same rules."""
    width = in_width
    for i, layer in enumerate(layers):
        w, b = layer.weights, layer.biases
        if w.ndim != 2 or w.shape[1] != width or not 1 <= w.shape[0] <= MAX_WIDTH:
            raise _fail(f"layer {i} weights have shape {w.shape}, expected (1..{MAX_WIDTH}, "
                        f"{width})", index=i)
        if b.shape != (w.shape[0],):
            raise _fail(f"layer {i} biases have shape {b.shape}, expected ({w.shape[0]},)",
                        index=i)
        if not 2 <= layer.weight_bits <= MAX_WEIGHT_BITS:
            raise _fail(f"layer {i} weight_bits {layer.weight_bits} outside "
                        f"[2, {MAX_WEIGHT_BITS}]", index=i)
        limit = 1 << (layer.weight_bits - 1)
        if w.min() < -limit or w.max() >= limit:
            raise _fail(f"layer {i} weights exceed {layer.weight_bits} signed bits", index=i)
        if b.min() <= -BIAS_LIMIT or b.max() >= BIAS_LIMIT:
            raise _fail(f"layer {i} biases reach 2^52", index=i)
        if not 0 <= layer.shift <= MAX_SHIFT:
            raise _fail(f"layer {i} shift {layer.shift} outside [0, {MAX_SHIFT}]", index=i)
        width = w.shape[0]
    if out_lo.shape != (width,) or out_hi.shape != (width,):
        raise _fail(f"output ranges must have shape ({width},)")
    if (out_lo.min() < -OUTPUT_LIMIT or out_hi.max() > OUTPUT_LIMIT
            or np.any(out_lo > out_hi)):
        raise _fail("output ranges must satisfy -2^53 <= lo <= hi <= 2^53")
    for i, total in enumerate(worst_case_sums(layers, input_bounds)):
        if total > EXACT_LIMIT:
            raise _fail(f"layer {i} worst-case accumulator {total} exceeds 2^53: its sums "
                        "could overflow the exact integer range", index=i)


def layers_int64(layers, h: np.ndarray, act_bits: int, out_lo: np.ndarray,
                 out_hi: np.ndarray) -> np.ndarray:
    """The reference evaluation of integer layers on (N, in) int64 inputs -> (N, O) int64:
    accumulate, round by the shift, ReLU-clamp hidden layers to act_bits, clamp the output."""
    top = (1 << act_bits) - 1
    for i, layer in enumerate(layers):
        acc = h @ layer.weights.T + layer.biases
        if layer.shift:
            acc = (acc + (1 << (layer.shift - 1))) >> layer.shift
        last = i == len(layers) - 1
        h = np.clip(acc, out_lo, out_hi) if last else np.clip(acc, 0, top)
    return h


def layers_float64(layers, h: np.ndarray, act_bits: int, out_lo: np.ndarray,
                   out_hi: np.ndarray, buffers: list[np.ndarray] | None = None) -> np.ndarray:
    """:func:`layers_int64` through float64 BLAS, identical for layers that pass
    :func:`validate_layers` (``buffers``: optional per-layer (rows, out) work arrays)."""
    top = float((1 << act_bits) - 1)
    rows = h.shape[0]
    last = len(layers) - 1
    for i, layer in enumerate(layers):
        w, offset = _float_params(layer)
        acc = np.empty((rows, w.shape[1])) if buffers is None else buffers[i][:rows]
        # (x W^T + b + 2^(s-1)) * 2^-s with the power of two folded into W and b: every
        # partial sum is an integer <= 2^53 times 2^-s, so it stays exact.
        np.matmul(h, w, out=acc)
        acc += offset
        np.floor(acc, out=acc)
        if i == last:
            np.clip(acc, out_lo.astype(np.float64), out_hi.astype(np.float64), out=acc)
        else:
            np.clip(acc, 0.0, top, out=acc)
        h = acc
    return h.astype(np.int64)
