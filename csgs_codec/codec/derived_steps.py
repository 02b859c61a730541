"""Rotation steps derived from the decoded scales: no per-Gaussian side information (FORMAT
§12.8, mode 6).

A small rotation error changes a Gaussian's covariance in proportion to how unequal its axes
are: for axis ratio r = e^d the relative image error of a rotation by theta is
theta^2 (r - 1/r)^2 / 4 = theta^2 sinh(d)^2, zero for an isotropic Gaussian. The decoder has
every Gaussian's log-scales before its rotation, so both sides can put Gaussian i in a class by
its anisotropy d_i = max - min of its decoded log-scales, and code its rotation with the
class's step: ``step_index + offsets[class_i]``. The class table (thresholds on d and step
offsets) is chosen by the encoder and carried once per channel; the class of each Gaussian
costs nothing.

The class derivation reads decoded float32 values and uses binary64 subtraction and
comparison only, which are correctly rounded, so every machine derives the same classes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.entropy.residual import STEP_COUNT

#: Most classes a table may hold.
MAX_CLASSES = 8
#: Step indices per octave of the step table (FORMAT §16.3.1).
STEPS_PER_OCTAVE = 8
#: Anisotropy thresholds of the reference encoder (natural-log units: 0.25 is an axis ratio
#: of 1.28, 3 of 20).
THRESHOLDS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
#: The reference encoder's offsets follow sinh(d)^-1 scaled by this (1: the high-rate
#: optimum for equal image sensitivity; measured held-out, half of it was better on donut),
#: clipped to +-CLIP step indices.
STRENGTH = 0.5
CLIP = 12


@dataclass(frozen=True)
class DerivedSteps:
    """Per-Gaussian step classes of a rotation stream and the table that defines them.

    Attributes:
        thresholds: (K - 1,) float32, increasing, >= 0: class i is the number of thresholds
            t with t <= d_i.
        offsets: (K,) int64 step-index offset of each class.
        classes: (N,) int64 class of every Gaussian (derived, never coded).
    """

    thresholds: np.ndarray
    offsets: np.ndarray
    classes: np.ndarray

    @property
    def count(self) -> int:
        """Number of classes K."""
        return int(len(self.offsets))

    def step_indices(self, base: int) -> np.ndarray:
        """(N,) int64 step index of every Gaussian for a channel of step index ``base``."""
        return (base + self.offsets)[self.classes]


def anisotropy(log_scales: np.ndarray) -> np.ndarray:
    """d = max - min of each row of decoded log-scales (N, 3) float32, in binary64: (N,)."""
    s = np.asarray(log_scales, dtype=np.float32).astype(np.float64)
    if s.shape[0] == 0:
        return np.zeros(0, np.float64)
    return s.max(axis=1) - s.min(axis=1)


def derive_classes(log_scales: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """(N,) int64 class of each Gaussian: how many ``thresholds`` (float32) are <= its d."""
    t = np.asarray(thresholds, dtype=np.float32).astype(np.float64)
    return np.searchsorted(t, anisotropy(log_scales), side="right").astype(np.int64)


def check_table(thresholds: np.ndarray, offsets: np.ndarray, base: int) -> str | None:
    """Why a class table is invalid for a channel of step index ``base``, or None."""
    k = len(offsets)
    if not 1 <= k <= MAX_CLASSES:
        return f"class count {k} outside 1..{MAX_CLASSES}"
    t = np.asarray(thresholds, dtype=np.float64)
    if len(t) != k - 1:
        return f"{len(t)} thresholds for {k} classes"
    if len(t) and (not np.all(np.isfinite(t)) or t[0] < 0 or np.any(np.diff(t) <= 0)):
        return "thresholds must be finite, >= 0 and strictly increasing"
    steps = base + np.asarray(offsets, dtype=np.int64)
    if len(steps) and (steps.min() < 0 or steps.max() >= STEP_COUNT):
        return f"step index {base} plus offsets {list(map(int, offsets))} leaves [0, {STEP_COUNT})"
    return None


def rotation_steps(log_scales: np.ndarray, base: int, *, strength: float = STRENGTH,
                   clip: int = CLIP) -> DerivedSteps | None:
    """The reference encoder's table for rotations of Gaussians with decoded ``log_scales``
    (N, 3), quantized at step index ``base``; None when every class would keep the step.

    Class c gets a step multiplier m_c ~ mean_c(sinh(d)^2)^(-strength / 2), normalised so that
    the count-weighted mean of log2 m_c is 0 (about the same rate), in 1/8 octaves, clipped
    to +-``clip`` and to the step table.
    """
    thresholds = np.array(THRESHOLDS, np.float32)
    classes = derive_classes(log_scales, thresholds)
    k = len(thresholds) + 1
    d = np.minimum(anisotropy(log_scales), 20.0)
    count = np.bincount(classes, minlength=k).astype(np.float64)
    sens = np.bincount(classes, weights=np.sinh(d) ** 2, minlength=k) / np.maximum(count, 1)
    log_m = -0.5 * strength * np.log2(np.maximum(sens, 1e-12))
    if count.sum():
        log_m -= np.sum(count * log_m) / count.sum()
    offsets = np.clip(np.rint(STEPS_PER_OCTAVE * log_m), -clip, clip).astype(np.int64)
    offsets = np.clip(base + offsets, 0, STEP_COUNT - 1) - base
    offsets[count == 0] = 0  # no Gaussian in the class: any offset, 0 is the plainest
    if not np.any(offsets[count > 0]):
        return None
    return DerivedSteps(thresholds, offsets, classes)
