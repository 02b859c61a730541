"""Float streams: N x C attribute values quantized per channel and range coded (FORMAT §12.8).

Each channel c is one of:

- constant (mode 0): one float32 for every Gaussian, no bits per Gaussian;
- factorized (mode 1): quantization indices k = round((a - mu) / q) on the value grid, coded
  with one frozen Gaussian table;
- predicted (mode 2): k is predicted from the indices of the channels before it (a
  channel-wise autoregressive model, linear with integer coefficients):
  ``P = floor((sum_j A_j * k_j + B) / 2^12)`` in exact int64, and ``k - P`` is coded.
- histogram (mode 4): k or k - P (with or without the prediction) coded with a frequency
  table of its own (:mod:`csgs_codec.entropy.histogram`) instead of a frozen Gaussian table,
  for channels whose distribution is not Gaussian.
- hyperprior (mode 5): k or k - P (the *base residual* b) coded per Gaussian with the mean
  and scale-table index the color layer's INR hyperprior predicts from the Gaussian's
  position (:class:`ChannelPrior`): the symbol b - mean is coded with that scale's table.

- derived steps (mode 6, rotation streams only): as factorized or predicted, but the step of
  Gaussian i is ``step_index + offsets[class_i]`` with the class derived from its decoded
  log-scales (:mod:`csgs_codec.codec.derived_steps`), and each class has its own table.
- scored steps (mode 7, rotation streams only): as mode 6 with the class a cell of two scores
  of the decoded log-scales and opacity logit.

The value decodes as ``float32((mu + q * k) * 2^-F)``. The encoder picks, per channel, the mode
that codes smallest (counting the coefficients), so prediction is used only where it pays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.codec.derived_steps import (
    MAX_CLASSES,
    SCORE_FEATURES,
    DerivedSteps,
    ScoredSteps,
    check_scored_table,
    check_table,
    derive_classes,
    derive_scored_classes,
)
from csgs_codec.entropy.histogram import decode_histogram, encode_histogram, histogram_cost
from csgs_codec.entropy.residual import (
    STEP_COUNT,
    decode_symbols,
    encode_symbols,
    from_grid,
    quantize,
    reconstruct,
    step_index,
    step_size,
    to_grid,
)
from csgs_codec.entropy.table_choice import table_costs
from csgs_codec.entropy.tables import gaussian_family
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter

MODE_CONSTANT = 0
MODE_FACTORIZED = 1
MODE_PREDICTED = 2
MODE_HISTOGRAM = 4
MODE_HYPERPRIOR = 5
MODE_DERIVED = 6
MODE_SCORED = 7
#: Modes whose steps (and tables) follow per-Gaussian classes derived from decoded values.
CLASSED_MODES = (MODE_DERIVED, MODE_SCORED)
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
        mode: the best mode without the hyperprior (constant, factorized, predicted or
            histogram).
        cost: its coded size in bits (estimate, coefficients included).
        mean: the channel's grid mean (constant: unused).
        base: (N,) int64 base residual: the quantization index k, or k minus the channel
            prediction when ``coefs`` is set.
        coefs, bias: the channel prediction, or None.
        constant: the float32 value of a constant channel.
        tables: (K,) int64 table of each step class (derived and scored steps only).
    """

    mode: int
    cost: float
    mean: int = 0
    base: np.ndarray | None = None
    coefs: np.ndarray | None = None
    bias: int = 0
    constant: float = 0.0
    tables: np.ndarray | None = None


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
        recon: (N, C) float32 values the decoder will reconstruct (whatever the modes).
        derived: the step classes every coded channel follows (:class:`DerivedSteps`, mode
            6, or :class:`ScoredSteps`, mode 7), or None.
    """

    count: int
    frac_bits: int
    step_idx: int
    channels: list[ChannelPlan]
    recon: np.ndarray
    derived: DerivedSteps | ScoredSteps | None = None

    def lattice(self) -> Lattice:
        """This plan's :class:`Lattice`."""
        return Lattice(self.frac_bits, tuple(int(ch.mean) for ch in self.channels))


@dataclass(frozen=True)
class ChannelPrior:
    """Per-Gaussian entropy parameters of one channel from the color hyperprior.

    Attributes:
        mean: (N,) int64 rounded mean of the base residual, in steps (may be a strided view).
        scale: (N,) int64 scale-table indices in [0, 63] (may be a strided view).
    """

    mean: np.ndarray
    scale: np.ndarray


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
    mode without a hyperprior.

    ``derive``, when given, is called with the stream's step index and returns the
    :class:`DerivedSteps` (mode 6) or :class:`ScoredSteps` (mode 7) every coded channel then
    follows, or None for one step.
    ``lattice``, when given, fixes the grid and the channels' means instead of taking them
    from ``values`` (a channel constant in ``values`` is still coded as a constant); not
    with ``derive``.
    """
    n, channels = values.shape
    if lattice is not None and (derive is not None or len(lattice.means) != channels):
        raise InputError("a fixed lattice needs one mean per channel and no derived steps",
                         property="lattice")
    f = frac_bits_for(values) if lattice is None else lattice.frac_bits
    recon = np.empty((n, channels), np.float32)
    indices = np.zeros((channels, n), np.int64)  # channels as rows, as in the reader
    step_idx = int(step_index(np.array([step * 2.0**f]))[0])
    derived = derive(step_idx) if derive is not None and n else None
    if derived is not None:
        return _plan_derived(values, f, step_idx, derived)
    steps = np.full(n, step_idx, np.int64)
    plans = []
    for c in range(channels):
        column = values[:, c].astype(np.float32)
        if n == 0 or np.all(column == column[0]):
            value = float(column[0]) if n else 0.0
            plans.append(ChannelPlan(MODE_CONSTANT, 0.0, constant=value))
            recon[:, c] = np.float32(value)
            continue
        grid, mean, k = _median_quantized(column, f, steps,
                                          None if lattice is None else lattice.means[c])
        indices[c] = k
        candidates = [(float(table_costs(k).min()), MODE_FACTORIZED, k, None, 0),
                      (histogram_cost(k), MODE_HISTOGRAM, k, None, 0)]
        fitted = _fit_prediction(indices[:c].T, k)
        if fitted is not None:
            coefs, bias = fitted
            r = k - predict(indices[:c], coefs, bias)
            overhead = 8 * (3 * c + 6)  # coefficient bytes, at most
            candidates += [(float(table_costs(r).min()) + overhead, MODE_PREDICTED, r, coefs,
                            bias),
                           (histogram_cost(r) + overhead, MODE_HISTOGRAM, r, coefs, bias)]
        cost, mode, base, coefs, bias = min(candidates, key=lambda cand: cand[0])
        plans.append(ChannelPlan(mode, cost, mean, base, coefs, bias))
        means = np.full(n, mean, np.int64)
        recon[:, c] = from_grid(reconstruct(means, k, steps), f).astype(np.float32)
    return StreamPlan(n, f, step_idx, plans, recon)


def _class_members(classes: np.ndarray, count: int) -> list[np.ndarray]:
    """The rows of each class 0..count-1 (one stable radix sort instead of a mask each)."""
    order = np.argsort(classes.astype(np.uint8), kind="stable")
    bounds = np.searchsorted(classes[order], np.arange(count + 1))
    return [order[bounds[c]:bounds[c + 1]] for c in range(count)]


def _class_costs(residuals: np.ndarray, members: list[np.ndarray]
                 ) -> tuple[float, np.ndarray]:
    """(bits, (K,) best table per class) of ``residuals`` coded with one table per class
    (``members``: the rows of each class, :func:`_class_members`)."""
    count = len(members)
    tables = np.zeros(count, np.int64)
    bits = 0.0
    for c in range(count):
        member = residuals[members[c]]
        if member.size:
            costs = table_costs(member)
            tables[c] = int(np.argmin(costs))
            bits += float(costs[tables[c]])
    return bits + 8 * count, tables


def _plan_derived(values: np.ndarray, f: int, step_idx: int,
                  derived: DerivedSteps | ScoredSteps) -> StreamPlan:
    """The plan of a stream whose coded channels all follow ``derived`` (mode 6 or 7)."""
    n, channels = values.shape
    if isinstance(derived, ScoredSteps):
        mode = MODE_SCORED
        why = check_scored_table(derived.weights, derived.thresholds_u, derived.thresholds_v,
                                 derived.offsets, step_idx)
    else:
        mode = MODE_DERIVED
        why = check_table(derived.thresholds, derived.offsets, step_idx)
    if why is not None:
        raise InputError(why, property="derive")
    recon = np.empty((n, channels), np.float32)
    indices = np.zeros((channels, n), np.int64)
    steps = derived.step_indices(step_idx)
    table_bits = derived.table_bits
    members = _class_members(derived.classes, derived.count)
    plans = []
    for c in range(channels):
        column = values[:, c].astype(np.float32)
        if np.all(column == column[0]):
            plans.append(ChannelPlan(MODE_CONSTANT, 0.0, constant=float(column[0])))
            recon[:, c] = column[0]
            continue
        grid, mean, k = _median_quantized(column, f, steps)
        indices[c] = k
        bits, tables = _class_costs(k, members)
        best = ChannelPlan(mode, bits + table_bits, mean, k, None, 0, tables=tables)
        fitted = _fit_prediction(indices[:c].T, k)
        if fitted is not None:
            coefs, bias = fitted
            r = k - predict(indices[:c], coefs, bias)
            bits, tables = _class_costs(r, members)
            bits += table_bits + 8 * (3 * c + 6)
            if bits < best.cost:
                best = ChannelPlan(mode, bits, mean, r, coefs, bias, tables=tables)
        plans.append(best)
        means = np.full(n, mean, np.int64)
        recon[:, c] = from_grid(reconstruct(means, k, steps), f).astype(np.float32)
    return StreamPlan(n, f, step_idx, plans, recon, derived)


def prior_stream(plan: ChannelPlan, prior: ChannelPrior) -> bytes:
    """The residual stream of ``plan``'s channel coded with the hyperprior (mode 5)."""
    return encode_symbols(plan.base - prior.mean, prior.scale)


def write_planned_stream(out: ByteWriter, plan: StreamPlan,
                         priors: dict[int, tuple[ChannelPrior, bytes]] | None = None) -> None:
    """Append the stream body of ``plan``; channels in ``priors`` (channel -> (prior, its
    :func:`prior_stream`)) are written in the hyperprior mode, the others in their plan's."""
    priors = priors or {}
    out.varint(plan.count)
    out.fixed("u8", len(plan.channels))
    out.fixed("u8", plan.frac_bits)
    for c, ch in enumerate(plan.channels):
        if ch.mode == MODE_CONSTANT:
            out.fixed("u8", MODE_CONSTANT)
            out.fixed("f32", ch.constant)
            continue
        if ch.mode in CLASSED_MODES:
            _write_derived_channel(out, plan, ch, c)
            continue
        mode = MODE_HYPERPRIOR if c in priors else ch.mode
        out.fixed("u8", mode)
        out.svarint(ch.mean)
        if mode in (MODE_FACTORIZED, MODE_PREDICTED):
            table = int(np.argmin(table_costs(ch.base)))
            out.fixed("u8", table)
        out.fixed("u8", plan.step_idx)
        if mode == MODE_PREDICTED:
            out.varint(c)
        elif mode != MODE_FACTORIZED:
            out.varint(0 if ch.coefs is None else c)
        if ch.coefs is not None:
            for a in ch.coefs:
                out.svarint(int(a))
            out.svarint(int(ch.bias))
        if mode == MODE_HYPERPRIOR:
            out.byte_string(priors[c][1])
        elif mode == MODE_HISTOGRAM:
            out.byte_string(encode_histogram(ch.base))
        else:
            out.byte_string(encode_symbols(ch.base, np.full(plan.count, table, np.int64)))


def _write_derived_channel(out: ByteWriter, plan: StreamPlan, ch: ChannelPlan, c: int
                           ) -> None:
    """Append channel ``c``'s record in the derived- or scored-steps mode (FORMAT §12.8)."""
    derived = plan.derived
    out.fixed("u8", ch.mode)
    out.svarint(ch.mean)
    out.fixed("u8", plan.step_idx)
    if ch.mode == MODE_SCORED:
        for w in np.asarray(derived.weights, np.float32).ravel():
            out.fixed("f32", float(w))
        for thresholds in (derived.thresholds_u, derived.thresholds_v):
            out.fixed("u8", len(thresholds) + 1)
            for t in thresholds:
                out.fixed("f32", float(t))
    else:
        out.fixed("u8", derived.count)
        for t in derived.thresholds:
            out.fixed("f32", float(t))
    for o in derived.offsets:
        out.svarint(int(o))
    for table in ch.tables:
        out.fixed("u8", int(table))
    out.varint(0 if ch.coefs is None else c)
    if ch.coefs is not None:
        for a in ch.coefs:
            out.svarint(int(a))
        out.svarint(int(ch.bias))
    out.byte_string(encode_symbols(ch.base, ch.tables[derived.classes]))


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
    :class:`ChannelPrior`); a channel in mode 5 without one is an error. ``log_scales`` and
    ``opacity`` are callables returning the scene's decoded log-scales (N, 3) and opacity
    logits (N, 1) float32, which channels in modes 6 and 7 derive their steps from; None
    where those modes are not allowed (every stream but ROTN).

    Raises:
        FormatError: count or channel mismatch, a bad mode, table, step or coefficient, an
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
    tables = gaussian_family().count
    class_cache: dict[tuple, np.ndarray] = {}  # channels with one class table share classes
    for c in range(c_count):
        mode = r.fixed("u8", "mode")
        if mode == MODE_CONSTANT:
            out[c] = np.float32(r.fixed("f32", "constant_value"))
            continue
        if mode in CLASSED_MODES:
            if log_scales is None or (mode == MODE_SCORED and opacity is None):
                raise r.error(f"channel {c}: derived steps (mode {mode}) are only allowed "
                              "in ROTN")
            k, q = _read_derived_channel(r, c, n, indices, peak, mode, log_scales, opacity,
                                         class_cache)
            mean = k[1]
            k = k[0]
            top = int(np.abs(k).max()) if n else 0
            peak = max(peak, top)
            indices[c] = k
            out[c] = from_grid(k * q + np.int64(mean), f)
            continue
        if mode not in (MODE_FACTORIZED, MODE_PREDICTED, MODE_HISTOGRAM, MODE_HYPERPRIOR):
            raise r.error(f"channel {c} has unknown mode {mode}")
        prior = None
        if mode == MODE_HYPERPRIOR:
            prior = (priors or {}).get(c)
            if prior is None:
                raise r.error(f"channel {c} uses the color hyperprior, which does not model "
                              "it (no CHYP chunk, or its channel mask leaves it out)")
        mean = r.svarint("mean")
        table = 0 if mode in (MODE_HISTOGRAM, MODE_HYPERPRIOR) else r.fixed("u8", "scale_index")
        step = r.fixed("u8", "step_index")
        if abs(mean) > 1 << 53 or table >= tables or step >= STEP_COUNT:
            raise r.error(f"channel {c}: mean, scale index or step index out of range")
        prediction = 0
        m = 0
        if mode in (MODE_HISTOGRAM, MODE_HYPERPRIOR):
            m = r.varint("coefficient_count", maximum=c_count)
            if m not in (0, c):
                raise r.error(f"channel {c} has {m} coefficients, expected 0 or {c}")
        if mode == MODE_PREDICTED or m:
            m = r.varint("coefficient_count", maximum=c_count) if mode == MODE_PREDICTED else m
            if m != c:
                raise r.error(f"channel {c} has {m} coefficients, expected {c}")
            coefs = np.array([r.svarint("coefficient") for _ in range(m)], np.int64)
            bias = r.svarint("bias")
            if (m and np.abs(coefs).max() >= COEF_LIMIT) or abs(bias) >= BIAS_LIMIT:
                raise r.error(f"channel {c}: prediction coefficient out of range")
            if peak >= INDEX_LIMIT:
                raise r.error(f"channel {c}: earlier indices too large to predict from")
            prediction = predict(indices[:c], coefs, bias)
        stream = r.byte_string("residual_stream")
        if mode == MODE_HYPERPRIOR:
            k = decode_symbols(stream, prior.scale, chunk=r.chunk,
                               base_offset=r.offset - len(stream)) + prior.mean + prediction
        elif mode == MODE_HISTOGRAM:
            k = decode_histogram(stream, n, chunk=r.chunk,
                                 base_offset=r.offset - len(stream)) + prediction
        else:
            k = decode_symbols(stream, np.full(n, table, np.int64), chunk=r.chunk,
                               base_offset=r.offset - len(stream)) + prediction
        q = int(step_size(np.array([step]))[0])
        top = int(np.abs(k).max()) if n else 0
        if top > ((1 << 53) - abs(mean)) // q:
            raise r.error(f"channel {c}: decoded value exceeds 2^53 on its grid")
        peak = max(peak, top)
        indices[c] = k
        values = k * np.int64(q) + np.int64(mean)  # mu + q k, bounded by 2^53 just above
        out[c] = from_grid(values, f)
    return np.ascontiguousarray(out.T)


def _read_derived_channel(r: ByteReader, c: int, n: int, indices: np.ndarray, peak: int,
                          mode: int, log_scales, opacity, class_cache: dict
                          ) -> tuple[tuple[np.ndarray, int], np.ndarray]:
    """((indices k (N,), mean), per-Gaussian steps q (N,)) of a channel in mode 6 or 7, the
    reader just past its mode byte (FORMAT §12.8); ``class_cache`` keeps the classes of
    each class table read so far in the stream."""
    mean = r.svarint("mean")
    step = r.fixed("u8", "step_index")
    if abs(mean) > 1 << 53 or step >= STEP_COUNT:
        raise r.error(f"channel {c}: mean or step index out of range")
    if mode == MODE_SCORED:
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
    else:
        k_count = r.fixed("u8", "class_count")
        if not 1 <= k_count <= MAX_CLASSES:
            raise r.error(f"channel {c}: class count {k_count} outside 1..{MAX_CLASSES}")
        at = r.offset
        thresholds = np.array([r.fixed("f32", "threshold") for _ in range(k_count - 1)],
                              np.float32)
        offsets = np.array([r.svarint("step_offset") for _ in range(k_count)], np.int64)
        why = check_table(thresholds, offsets, step)
    if why is not None:
        raise FormatError(f"channel {c}: {why}", chunk=r.chunk, offset=at)
    tables = np.array([r.fixed("u8", "scale_index") for _ in range(k_count)], np.int64)
    if tables.max() >= gaussian_family().count:
        raise r.error(f"channel {c}: scale index {int(tables.max())} out of range")
    m = r.varint("coefficient_count", maximum=c)
    prediction = 0
    if m:
        if m != c:
            raise r.error(f"channel {c} has {m} coefficients, expected 0 or {c}")
        coefs = np.array([r.svarint("coefficient") for _ in range(m)], np.int64)
        bias = r.svarint("bias")
        if np.abs(coefs).max() >= COEF_LIMIT or abs(bias) >= BIAS_LIMIT:
            raise r.error(f"channel {c}: prediction coefficient out of range")
        if peak >= INDEX_LIMIT:
            raise r.error(f"channel {c}: earlier indices too large to predict from")
        prediction = predict(indices[:c], coefs, bias)
    stream = r.byte_string("residual_stream")
    if mode == MODE_SCORED:
        key = (mode, weights.tobytes(), bins[0].tobytes(), bins[1].tobytes())
        if key not in class_cache:
            class_cache[key] = derive_scored_classes(log_scales(), opacity(), weights,
                                                     bins[0], bins[1])
    else:
        key = (mode, thresholds.tobytes())
        if key not in class_cache:
            class_cache[key] = derive_classes(log_scales(), thresholds)
    classes = class_cache[key]
    k = decode_symbols(stream, tables[classes], chunk=r.chunk,
                       base_offset=r.offset - len(stream)) + prediction
    q = step_size(step + offsets)[classes]
    room = (1 << 53) - abs(mean)
    if n and np.any(np.abs(k) > room // q):
        raise r.error(f"channel {c}: decoded value exceeds 2^53 on its grid")
    return (k, mean), q


def _median_quantized(column: np.ndarray, frac_bits: int, steps,
                      mean: int | None = None) -> tuple[np.ndarray, int, np.ndarray]:
    """A channel's values on the fixed-point grid (N,) int64, their ``mean`` (the median
    unless given) and the quantization indices (N,) of the values around it with ``steps``."""
    grid = to_grid(column.astype(np.float64), frac_bits)
    if mean is None:
        mean = int(np.rint(np.median(grid)))
    return grid, mean, quantize(grid, np.full(len(grid), mean, np.int64), steps)
