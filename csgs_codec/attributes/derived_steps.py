"""Rotation steps derived from decoded attributes: no per-Gaussian side information (FORMAT
§12.8, scored steps).

A small rotation error changes a Gaussian's covariance in proportion to how unequal its axes
are: for axis ratio r = e^d the relative image error of a rotation by theta is
theta^2 (r - 1/r)^2 / 4 = theta^2 sinh(d)^2, zero for an isotropic Gaussian; and the picture
a Gaussian changes grows with its area and opacity. The decoder has every Gaussian's
log-scales and opacity before its rotation, so both sides can put Gaussian i in a class, a
cell of two *scores* of those decoded values, each a weighted sum of its sorted log-scales
and its opacity logit clamped at 0, and code its rotation with the class's step:
``step_index + offsets[class_i]``. The table (weights, thresholds and step offsets) is
chosen by the encoder and carried once per channel; the class of each Gaussian costs
nothing. The reference encoder scores u = log area + 2 log opacity (the two largest
log-scales plus twice the clamped logit) and v = the anisotropy, so a faint or small
Gaussian's rotation is coded coarser than that of a large, opaque, elongated one
(:func:`footprint_steps`).

The class derivation reads decoded float32 values and uses binary64 products (exact on
float32 inputs), sums in a fixed order and comparisons only, each correctly rounded, so every
machine derives the same classes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.entropy.residual import STEP_COUNT

#: Most bins of each score.
MAX_CLASSES = 8
#: Features a score weighs: the sorted log-scales (largest first) and the opacity logit
#: clamped at 0.
SCORE_FEATURES = 4
#: Step indices per octave of the step table (FORMAT §16.3.1).
STEPS_PER_OCTAVE = 8
#: The reference encoder's anisotropy bins (score v, natural-log units: 0.25 is an axis
#: ratio of 1.28, 3 of 20).
THRESHOLDS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)


@dataclass(frozen=True)
class ScoredSteps:
    """Per-Gaussian step classes from two scores of decoded attributes (FORMAT §12.8).

    Attributes:
        weights: (2, 4) float32, finite: the weights of score u (row 0) and score v (row 1)
            on the features of :func:`score_features`.
        thresholds_u, thresholds_v: float32, finite, strictly increasing: the bin of a score
            is the number of its thresholds at or below it (K_u, K_v = lengths + 1, <= 8).
        offsets: (K_u * K_v,) int64 step-index offset of each cell, cell = bin_u * K_v + bin_v.
        classes: (N,) int64 cell of every Gaussian (derived, never coded).
    """

    weights: np.ndarray
    thresholds_u: np.ndarray
    thresholds_v: np.ndarray
    offsets: np.ndarray
    classes: np.ndarray

    @property
    def count(self) -> int:
        """Number of cells K_u * K_v."""
        return int(len(self.offsets))

    def step_indices(self, base: int) -> np.ndarray:
        """(N,) int64 step index of every Gaussian for a channel of step index ``base``."""
        return (base + self.offsets)[self.classes]

    @property
    def table_bits(self) -> int:
        """Bits the cell table takes in each channel record (offsets at one byte each)."""
        thresholds = len(self.thresholds_u) + len(self.thresholds_v)
        return 8 * (32 + 2 + 4 * thresholds + 2 * self.count)


def score_features(log_scales: np.ndarray, opacity: np.ndarray) -> np.ndarray:
    """(4, N) binary64 score features from decoded float32 log-scales (N, 3) and opacity
    logits (N,) or (N, 1), one row each: the log-scales sorted largest first, then
    min(logit, 0)."""
    s = np.asarray(log_scales, np.float32)
    n = len(s)
    out = np.empty((4, n), np.float64)
    a, b, c = (s[:, j].astype(np.float64) for j in range(3))
    low, high = np.minimum(a, b), np.maximum(a, b)
    # Selections only (no arithmetic): the sorted values are the decoded values exactly.
    np.maximum(high, c, out=out[0])
    np.minimum(low, c, out=out[2])
    np.minimum(high, c, out=high)
    np.maximum(low, high, out=out[1])
    np.minimum(np.asarray(opacity, np.float32).reshape(-1), 0.0, out=out[3])
    return out


def score(features: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(N,) binary64 score ((w0 f0 + w1 f1) + w2 f2) + w3 f3 of ``features`` (4, N), in that
    order (FORMAT §12.8)."""
    w = np.asarray(weights, np.float32).astype(np.float64)
    total = features[0] * w[0]
    term = np.empty_like(total)
    for j in range(1, SCORE_FEATURES):
        np.multiply(features[j], w[j], out=term)
        total += term
    return total


def derive_scored_classes(log_scales: np.ndarray, opacity: np.ndarray, weights: np.ndarray,
                          thresholds_u: np.ndarray, thresholds_v: np.ndarray) -> np.ndarray:
    """(N,) int64 cell bin_u * K_v + bin_v of each Gaussian."""
    features = score_features(log_scales, opacity)
    return _cells(score(features, weights[0]), score(features, weights[1]), thresholds_u,
                  thresholds_v)


def _cells(u: np.ndarray, v: np.ndarray, thresholds_u: np.ndarray,
           thresholds_v: np.ndarray) -> np.ndarray:
    """(N,) int64 cell bin_u * K_v + bin_v of scores u, v (N,) binary64."""
    bins = [np.searchsorted(np.asarray(t, np.float32).astype(np.float64), x, side="right")
            for x, t in ((u, thresholds_u), (v, thresholds_v))]
    return (bins[0] * (len(thresholds_v) + 1) + bins[1]).astype(np.int64)


def check_scored_table(weights: np.ndarray, thresholds_u: np.ndarray,
                       thresholds_v: np.ndarray, offsets: np.ndarray, base: int) -> str | None:
    """Why a scored-step table is invalid for a channel of step index ``base``, or None."""
    if not np.all(np.isfinite(np.asarray(weights, np.float64))):
        return "score weights must be finite"
    for name, t in (("u", thresholds_u), ("v", thresholds_v)):
        t = np.asarray(t, np.float64)
        if not len(t) < MAX_CLASSES:
            return f"{len(t) + 1} bins of score {name}, at most {MAX_CLASSES}"
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            return f"thresholds of score {name} must be finite and strictly increasing"
    cells = (len(thresholds_u) + 1) * (len(thresholds_v) + 1)
    if len(offsets) != cells:
        return f"{len(offsets)} step offsets for {cells} cells"
    steps = base + np.asarray(offsets, np.int64)
    if steps.min() < 0 or steps.max() >= STEP_COUNT:
        return f"step index {base} plus offsets {list(map(int, offsets))} leaves [0, {STEP_COUNT})"
    return None


#: Weights of the reference encoder's scores: u = log area x opacity^2 (two largest
#: log-scales + 2 x clamped logit), v = anisotropy (largest - smallest log-scale).
FOOTPRINT_WEIGHTS = ((1.0, 1.0, 0.0, 2.0), (1.0, 0.0, -1.0, 0.0))
#: Quantile bins of u, and the strength and clip of the reference encoder's footprint table
#: (measured on held-out views of donut, plant and biker: 0.5 of the high-rate optimum).
FOOTPRINT_BINS = 8
FOOTPRINT_STRENGTH = 0.5
FOOTPRINT_CLIP = 12
#: Fewest Gaussians a stream needs before the footprint table pays for its 64 cells.
FOOTPRINT_MIN_GAUSSIANS = 4096


def footprint_steps(log_scales: np.ndarray, opacity: np.ndarray, base: int, *,
                    strength: float = FOOTPRINT_STRENGTH, clip: int = FOOTPRINT_CLIP
                    ) -> ScoredSteps | None:
    """The reference encoder's scored-step table for rotations of Gaussians with decoded
    ``log_scales`` (N, 3) and opacity logits (N,), quantized at step index ``base``; None
    for scenes under :data:`FOOTPRINT_MIN_GAUSSIANS` or when every cell keeps the step.

    A small rotation by theta of a Gaussian of axis ratio e^d changes its picture by about
    theta^2 sinh(d)^2 of its energy, which is about its area times its opacity squared, so
    each cell's sensitivity is taken as the mean of exp(u) sinh(v)^2 over its Gaussians and
    its step multiplier as that to the power -strength/2 (1: the high-rate optimum),
    normalised to a count-weighted mean log-step of 0, in 1/8 octaves, clipped to +-``clip``
    and to the step table. No render is needed.
    """
    n = len(log_scales)
    if n < FOOTPRINT_MIN_GAUSSIANS:
        return None
    weights = np.array(FOOTPRINT_WEIGHTS, np.float32)
    features = score_features(log_scales, opacity)
    u = score(features, weights[0])
    v = score(features, weights[1])
    edges = np.unique(np.quantile(u, np.linspace(0, 1, FOOTPRINT_BINS + 1)[1:-1])
                      .astype(np.float32))
    thresholds_u = edges[np.isfinite(edges)]
    thresholds_v = np.array(THRESHOLDS, np.float32)
    classes = _cells(u, v, thresholds_u, thresholds_v)
    k = (len(thresholds_u) + 1) * (len(thresholds_v) + 1)
    count = np.bincount(classes, minlength=k).astype(np.float64)
    log_sens = u + 2.0 * np.log(np.sinh(np.clip(v, 1e-6, 20.0)))
    top = np.full(k, -np.inf)
    np.maximum.at(top, classes, log_sens)
    safe_top = np.where(np.isfinite(top), top, 0.0)
    sums = np.bincount(classes, weights=np.exp(log_sens - safe_top[classes]), minlength=k)
    log_mean = (safe_top + np.log(np.maximum(sums, 1e-300))
                - np.log(np.maximum(count, 1.0))) / np.log(2.0)
    log_m = -0.5 * strength * log_mean
    present = count > 0
    log_m -= np.sum(count[present] * log_m[present]) / count.sum()
    offsets = np.clip(np.rint(STEPS_PER_OCTAVE * log_m), -clip, clip)
    offsets = np.where(present, offsets, 0).astype(np.int64)
    offsets = np.clip(base + offsets, 0, STEP_COUNT - 1) - base
    if not np.any(offsets[present]):
        return None
    return ScoredSteps(weights, thresholds_u, thresholds_v, offsets, classes)


#: How the rotation stream's steps may follow decoded attributes (``EncoderConfig``
#: ``rotation_steps``, ``csgs encode --rotation-steps``).
ROTATION_RULES = ("footprint", "uniform")


def rotation_classes(rule: str, log_scales: np.ndarray, opacity: np.ndarray):
    """What makes the rotation stream's step classes under ``rule`` ("footprint" or
    "uniform") from decoded ``log_scales`` (N, 3) and opacity logits (N, 1) or (N,): the
    ``derive`` callable of :func:`csgs_codec.attributes.float_stream.plan_float_stream`, or None
    for one step."""
    if rule == "uniform":
        return None
    return lambda base: footprint_steps(log_scales, opacity, base)
