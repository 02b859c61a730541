"""Float streams: N x C attribute values quantized per channel and range coded (FORMAT §12.8).

Each channel is a constant (one float32, no bits per Gaussian) or quantization indices
k = round((a - mu) / q) on the value grid, decoded as ``float32((mu + q * k) * 2^-F)``. A coded
channel's record says, in its ``coding`` byte
(:class:`csgs_codec.attributes.channel_coders.Coding`):

- where its residuals' tables come from (:mod:`csgs_codec.attributes.channel_coders`): frozen
  Gaussian tables, a frequency table of its own (histogram), or the color layer's INR
  hyperprior, which predicts a mean and a table per Gaussian from its position;
- whether k is predicted from the indices of the channels before it (a channel-wise
  autoregressive model, linear with integer coefficients):
  ``P = floor((sum_j A_j * k_j + B) / 2^12)`` in exact int64, and ``k - P`` is coded;
- whether its steps follow *scored classes* (rotation streams only): the step of Gaussian i
  is ``step_index + offsets[class_i]`` with the class a cell of two scores of its decoded
  log-scales and opacity logit (:mod:`csgs_codec.attributes.derived_steps`), one table per class.

The encoder picks, per channel, what codes smallest (counting the coefficients), so
prediction is used only where it pays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.attributes.channel_coders import (
    CODERS,
    PLANNED_CODERS,
    TABLE_CONSTANT,
    TABLE_FROZEN,
    TABLE_PRIOR,
    ChannelContext,
    ChannelPrior,
    Coding,
)
from csgs_codec.attributes.derived_steps import (
    MAX_CLASSES,
    SCORE_FEATURES,
    ScoredSteps,
    check_scored_table,
    derive_scored_classes,
)
from csgs_codec.entropy.residual import (
    STEP_COUNT,
    from_grid,
    quantize,
    reconstruct,
    step_index,
    step_size,
    to_grid,
)
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter

__all__ = ["ChannelPlan", "ChannelPrior", "Lattice", "StreamPlan", "frac_bits_for",
           "plan_float_stream", "predict", "prior_stream", "read_float_stream",
           "write_float_stream", "write_planned_stream"]

#: Fractional bits of prediction coefficients and bias.
COEF_FRAC_BITS = 12
#: |A_j| must stay below this; |B| below BIAS_LIMIT.
COEF_LIMIT = 1 << 15
BIAS_LIMIT = 1 << 40
#: Indices that feed a prediction must stay below this in magnitude (keeps sums in int64).
INDEX_LIMIT = 1 << 31
#: Finest value grid: values are coded as integers in units of 2^-frac_bits.
MAX_FRAC_BITS = 24
MAX_COUNT = 1 << 28


def frac_bits_for(values: np.ndarray) -> int:
    """Finest value grid (<= 24 fractional bits) on which ``values`` stay below 2^52."""
    top = float(np.max(np.abs(values))) if values.size else 0.0
    room = 52 - int(np.ceil(np.log2(top + 1.0)))
    return int(np.clip(room, 0, MAX_FRAC_BITS))


def predict(previous: np.ndarray, coefs: np.ndarray, bias: int) -> np.ndarray:
    """Predicted indices (N,) int64: floor((sum_j coefs_j previous_j + bias) / 2^12), exact.

    Args:
        previous: (m, N) int64 indices of the earlier channels, one row each, |k| < 2^31.
        coefs: (m,) int64, each |A| < 2^15.

    Integer multiply-adds are exact, so the order of the sum does not change the result;
    summing one contiguous row at a time is what makes it fast.
    """
    total = np.full(previous.shape[1], np.int64(bias), np.int64)
    for row, coef in zip(previous, coefs.astype(np.int64)):
        if coef:
            total += row.astype(np.int64, copy=False) * coef
    return total >> COEF_FRAC_BITS


@dataclass
class ChannelPlan:
    """The encoder's analysis of one channel before any hyperprior: what it codes without one.

    Attributes:
        table: the best table source without the hyperprior (``TABLE_CONSTANT``,
            ``TABLE_FROZEN`` or ``TABLE_HISTOGRAM``).
        cost: its coded size in bits (estimate, coefficients included).
        mean: the channel's grid mean (constant: unused).
        base: (N,) int64 base residual: the quantization index k, or k minus the channel
            prediction when ``coefs`` is set.
        coefs, bias: the channel prediction, or None.
        constant_value: the float32 value of a constant channel.
        fields: the table source's fields (frozen tables: (K,) int64 scale index per step
            class).
    """

    table: int
    cost: float
    mean: int = 0
    base: np.ndarray | None = None
    coefs: np.ndarray | None = None
    bias: int = 0
    constant_value: float = 0.0
    fields: np.ndarray | None = None

    @property
    def is_constant(self) -> bool:
        """Whether the channel is one float32 for every Gaussian."""
        return self.table == TABLE_CONSTANT


@dataclass(frozen=True)
class Lattice:
    """Where a planned stream's values can land: its grid's fractional bits and, per channel,
    the grid mean the quantization indices count from (constant channels: 0). Planning
    values that already lie on a plan's lattice with that lattice and step reconstructs
    them exactly (what refinement relies on)."""

    frac_bits: int
    means: tuple[int, ...]


@dataclass
class StreamPlan:
    """A float stream quantized and analysed, ready to write (see :func:`plan_float_stream`).

    Attributes:
        count, frac_bits, step_idx: N, the grid's fractional bits and the step index.
        channels: one :class:`ChannelPlan` per channel.
        recon: (N, C) float32 values the decoder will reconstruct (whatever the codings).
        scored: the scored step classes every coded channel follows, or None.
    """

    count: int
    frac_bits: int
    step_idx: int
    channels: list[ChannelPlan]
    recon: np.ndarray
    scored: ScoredSteps | None = None

    def lattice(self) -> Lattice:
        """This plan's :class:`Lattice`."""
        return Lattice(self.frac_bits, tuple(int(ch.mean) for ch in self.channels))


def write_float_stream(out: ByteWriter, values: np.ndarray, step: float) -> np.ndarray:
    """Append a float stream body for ``values`` (N, C) quantized with ``step`` (value units).

    Returns the (N, C) float32 values the decoder will reconstruct.
    """
    plan = plan_float_stream(values, step)
    write_planned_stream(out, plan)
    return plan.recon


def plan_float_stream(values: np.ndarray, step: float, derive=None,
                      lattice: Lattice | None = None) -> StreamPlan:
    """Quantize ``values`` (N, C) with ``step`` (value units) and choose each channel's best
    coding without a hyperprior.

    ``derive``, when given, is called with the stream's step index and returns the
    :class:`ScoredSteps` every coded channel then follows, or None for one step.
    ``lattice``, when given, fixes the grid and the channels' means instead of taking them
    from ``values`` (a channel constant in ``values`` is still coded as a constant); not
    with ``derive``.
    """
    n, channels = values.shape
    if lattice is not None and (derive is not None or len(lattice.means) != channels):
        raise InputError("a fixed lattice needs one mean per channel and no scored steps",
                         property="lattice")
    f = frac_bits_for(values) if lattice is None else lattice.frac_bits
    step_idx = int(step_index(np.array([step * 2.0**f]))[0])
    scored = derive(step_idx) if derive is not None and n else None
    if scored is not None:
        why = check_scored_table(scored.weights, scored.thresholds_u, scored.thresholds_v,
                                 scored.offsets, step_idx)
        if why is not None:
            raise InputError(why, property="derive")
        steps = scored.step_indices(step_idx)
        members = _class_members(scored.classes, scored.count)
        coders = (CODERS[TABLE_FROZEN],)  # scored steps code with one frozen table per class
        table_bits = scored.table_bits
    else:
        steps = np.full(n, step_idx, np.int64)
        members, coders, table_bits = None, PLANNED_CODERS, 0
    recon = np.empty((n, channels), np.float32)
    indices = np.zeros((channels, n), np.int64)  # channels as rows, as in the reader
    plans = []
    for c in range(channels):
        column = values[:, c].astype(np.float32)
        if n == 0 or np.all(column == column[0]):
            value = float(column[0]) if n else 0.0
            plans.append(ChannelPlan(TABLE_CONSTANT, 0.0, constant_value=value))
            recon[:, c] = np.float32(value)
            continue
        _, mean, k = _median_quantized(column, f, steps,
                                       None if lattice is None else lattice.means[c])
        indices[c] = k
        candidates = [(k, None, 0, 0)]
        fitted = _fit_prediction(indices[:c].T, k)
        if fitted is not None:
            coefs, bias = fitted
            overhead = 8 * (3 * c + 6)  # coefficient bytes, at most
            candidates.append((k - predict(indices[:c], coefs, bias), coefs, bias, overhead))
        best = None
        for base, coefs, bias, overhead in candidates:
            for coder in coders:
                bits, fields = coder.cost(base, members)
                bits += overhead + table_bits
                if best is None or bits < best.cost:
                    best = ChannelPlan(coder.table, bits, mean, base, coefs, bias,
                                       fields=fields)
        plans.append(best)
        means = np.full(n, mean, np.int64)
        recon[:, c] = from_grid(reconstruct(means, k, steps), f).astype(np.float32)
    return StreamPlan(n, f, step_idx, plans, recon, scored)


def _class_members(classes: np.ndarray, count: int) -> list[np.ndarray]:
    """The rows of each class 0..count-1 (one stable radix sort instead of a mask each)."""
    order = np.argsort(classes.astype(np.uint8), kind="stable")
    bounds = np.searchsorted(classes[order], np.arange(count + 1))
    return [order[bounds[c]:bounds[c + 1]] for c in range(count)]


def prior_stream(plan: ChannelPlan, prior: ChannelPrior) -> bytes:
    """The residual stream of ``plan``'s channel coded with the hyperprior."""
    return CODERS[TABLE_PRIOR].encode(plan.base, None, ChannelContext(len(plan.base),
                                                                      prior=prior))


def write_planned_stream(out: ByteWriter, plan: StreamPlan,
                         priors: dict[int, tuple[ChannelPrior, bytes]] | None = None) -> None:
    """Append the stream body of ``plan`` (FORMAT §12.8); channels in ``priors`` (channel ->
    (prior, its :func:`prior_stream`)) are written with the hyperprior's tables, the others
    with their plan's."""
    priors = priors or {}
    out.varint(plan.count)
    out.fixed("u8", len(plan.channels))
    out.fixed("u8", plan.frac_bits)
    scored = plan.scored
    context = ChannelContext(plan.count, None if scored is None else scored.classes,
                             1 if scored is None else scored.count)
    for c, ch in enumerate(plan.channels):
        if ch.is_constant:
            out.fixed("u8", Coding(TABLE_CONSTANT).byte)
            out.fixed("f32", ch.constant_value)
            continue
        table = TABLE_PRIOR if c in priors else ch.table
        out.fixed("u8", Coding(table, ch.coefs is not None, scored is not None).byte)
        out.svarint(ch.mean)
        out.fixed("u8", plan.step_idx)
        if scored is not None:
            _write_score_table(out, scored)
        coder = CODERS[table]
        coder.write_fields(out, ch.fields)
        if ch.coefs is not None:
            for a in ch.coefs:
                out.svarint(int(a))
            out.svarint(int(ch.bias))
        stream = (priors[c][1] if table == TABLE_PRIOR
                  else coder.encode(ch.base, ch.fields, context))
        out.byte_string(stream)


def _write_score_table(out: ByteWriter, scored: ScoredSteps) -> None:
    """Append a scored-step table: weights, the thresholds of both scores, the step offset
    of each cell (FORMAT §12.8)."""
    for w in np.asarray(scored.weights, np.float32).ravel():
        out.fixed("f32", float(w))
    for thresholds in (scored.thresholds_u, scored.thresholds_v):
        out.fixed("u8", len(thresholds) + 1)
        for t in thresholds:
            out.fixed("f32", float(t))
    for o in scored.offsets:
        out.svarint(int(o))


FIT_ROWS = 1 << 17
"""Most rows a prediction fit reads: beyond this the coefficients barely move and the
least-squares solve would grow the encode time faster than linearly with the scene."""


def _fit_rows(count: int) -> slice:
    """Evenly spaced rows (a stride over the canonical, spatially sorted order) for the fit."""
    return slice(None, None, max(1, -(-count // FIT_ROWS)))


def _fit_prediction(previous: np.ndarray, k: np.ndarray):
    """Least-squares integer coefficients predicting ``k`` from ``previous``, or None."""
    if previous.shape[1] == 0 or not np.any(previous):
        return None
    if np.abs(previous).max() >= INDEX_LIMIT or np.abs(k).max() >= INDEX_LIMIT:
        return None
    rows = _fit_rows(len(k))
    x = np.column_stack([previous[rows].astype(np.float64), np.ones(len(k[rows]))])
    solution, *_ = np.linalg.lstsq(x, k[rows].astype(np.float64), rcond=None)
    scale = float(1 << COEF_FRAC_BITS)
    coefs = np.clip(np.rint(solution[:-1] * scale), -COEF_LIMIT + 1, COEF_LIMIT - 1)
    bias = int(np.clip(np.rint(solution[-1] * scale + scale / 2), -BIAS_LIMIT + 1,
                       BIAS_LIMIT - 1))  # + 1/2 turns the floor into rounding
    return coefs.astype(np.int64), bias


def read_float_stream(r: ByteReader, count: int, channels: int | None = None,
                      priors: dict[int, ChannelPrior] | None = None,
                      log_scales=None, opacity=None) -> np.ndarray:
    """Read a float stream body written by :func:`write_float_stream`: (count, C) float32.

    ``priors`` holds the hyperprior's parameters of the channels it models (channel index ->
    :class:`ChannelPrior`); a channel coded with the hyperprior without one is an error.
    ``log_scales`` and ``opacity`` are callables returning the scene's decoded log-scales
    (N, 3) and opacity logits (N, 1) float32, which channels with scored steps derive their
    steps from; None where scored steps are not allowed (every stream but ROTN).

    Raises:
        FormatError: count or channel mismatch, a bad coding, table, step or coefficient, an
            index or value outside its range, or a bad residual stream.
    """
    n = r.varint("count", maximum=MAX_COUNT)
    if n != count:
        raise r.error(f"stream holds {n} values, the scene has {count} Gaussians")
    c_count = r.fixed("u8", "channel_count")
    if channels is not None and c_count != channels:
        raise r.error(f"stream has {c_count} channels, expected {channels}")
    f = r.fixed("u8", "frac_bits")
    if f > MAX_FRAC_BITS:
        raise r.error(f"frac_bits {f} exceeds {MAX_FRAC_BITS}")
    # Channels as rows: every per-channel pass below reads and writes contiguous memory.
    out = np.empty((c_count, n), np.float32)
    indices = np.zeros((c_count, n), np.int64)
    peak = 0  # largest |index| of the channels decoded so far
    class_cache: dict[tuple, np.ndarray] = {}  # channels with one score table share classes
    for c in range(c_count):
        coding = Coding.read(r, c)
        if coding.table == TABLE_CONSTANT:
            out[c] = np.float32(r.fixed("f32", "constant_value"))
            continue
        if coding.scored and (log_scales is None or opacity is None):
            raise r.error(f"channel {c}: scored steps are only allowed in ROTN")
        mean = r.svarint("mean")
        step = r.fixed("u8", "step_index")
        if abs(mean) > 1 << 53 or step >= STEP_COUNT:
            raise r.error(f"channel {c}: mean or step index out of range")
        if coding.scored:
            classes, offsets, class_count = _read_score_table(r, c, n, step, log_scales,
                                                             opacity, class_cache)
            q = step_size(step + offsets)[classes]
        else:
            classes, class_count = None, 1
            q = np.int64(step_size(np.array([step]))[0])
        context = ChannelContext(n, classes, class_count,
                                 (priors or {}).get(c) if coding.table == TABLE_PRIOR else None)
        coder = CODERS[coding.table]
        fields = coder.read_fields(r, c, context)
        prediction = 0
        if coding.predicted:
            coefs = np.array([r.svarint("coefficient") for _ in range(c)], np.int64)
            bias = r.svarint("bias")
            if (c and np.abs(coefs).max() >= COEF_LIMIT) or abs(bias) >= BIAS_LIMIT:
                raise r.error(f"channel {c}: prediction coefficient out of range")
            if peak >= INDEX_LIMIT:
                raise r.error(f"channel {c}: earlier indices too large to predict from")
            prediction = predict(indices[:c], coefs, bias)
        stream = r.byte_string("residual_stream")
        k = coder.decode(stream, fields, context, r.chunk, r.offset - len(stream)) + prediction
        magnitude = np.abs(k)
        top = int(magnitude.max()) if n else 0
        room = (1 << 53) - abs(mean)
        # One step: the largest index decides; per-Gaussian steps: each index against its own.
        over = (n and np.any(magnitude > room // q)) if coding.scored else top > room // q
        if over:
            raise r.error(f"channel {c}: decoded value exceeds 2^53 on its grid")
        peak = max(peak, top)
        indices[c] = k
        out[c] = from_grid(k * q + np.int64(mean), f)  # mu + q k, bounded by 2^53 just above
    return np.ascontiguousarray(out.T)


def _read_score_table(r: ByteReader, c: int, n: int, step: int, log_scales, opacity,
                      class_cache: dict) -> tuple[np.ndarray, np.ndarray, int]:
    """((N,) class of every Gaussian, (K,) step offsets, K) of channel ``c``'s scored-step
    table, the reader at its first weight (FORMAT §12.8); ``class_cache`` keeps the classes
    of each table read so far in the stream."""
    at = r.offset
    weights = np.array([r.fixed("f32", "score_weight") for _ in range(2 * SCORE_FEATURES)],
                       np.float32).reshape(2, SCORE_FEATURES)
    bins = []
    for name in ("u", "v"):
        b_count = r.fixed("u8", f"bin_count_{name}")
        if not 1 <= b_count <= MAX_CLASSES:
            raise r.error(f"channel {c}: {b_count} bins of score {name}, outside "
                          f"1..{MAX_CLASSES}")
        bins.append(np.array([r.fixed("f32", f"threshold_{name}")
                              for _ in range(b_count - 1)], np.float32))
    k_count = (len(bins[0]) + 1) * (len(bins[1]) + 1)
    offsets = np.array([r.svarint("step_offset") for _ in range(k_count)], np.int64)
    why = check_scored_table(weights, bins[0], bins[1], offsets, step)
    if why is not None:
        raise FormatError(f"channel {c}: {why}", chunk=r.chunk, offset=at)
    key = (weights.tobytes(), bins[0].tobytes(), bins[1].tobytes())
    if key not in class_cache:
        class_cache[key] = derive_scored_classes(log_scales(), opacity(), weights, bins[0],
                                                 bins[1])
    return class_cache[key], offsets, k_count


def _median_quantized(column: np.ndarray, frac_bits: int, steps,
                      mean: int | None = None) -> tuple[np.ndarray, int, np.ndarray]:
    """A channel's values on the fixed-point grid (N,) int64, their ``mean`` (the median
    unless given) and the quantization indices (N,) of the values around it with ``steps``."""
    grid = to_grid(column.astype(np.float64), frac_bits)
    if mean is None:
        mean = int(np.rint(np.median(grid)))
    return grid, mean, quantize(grid, np.full(len(grid), mean, np.int64), steps)
