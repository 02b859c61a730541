"""Coding forms of Gaussian attributes: invertible re-parametrisations a codec quantizes.

Everything a decoder runs here uses only correctly rounded IEEE operations (add, multiply,
divide, sqrt) in a fixed order, so a decoded scene is bit-identical on every machine; no
``log``/``exp``/``sigmoid`` appears on the decode side.

Rotations use the "smallest three" form: a unit quaternion is sign-canonical (the largest
component positive), the index of its largest-magnitude component is stored, and the other
three components, each in [-1/sqrt(2), 1/sqrt(2)], are scaled by sqrt(2) into [-1, 1]. Unlike
dropping ``w`` alone, this keeps the reconstruction error of the dropped component bounded.

A Gaussian has four rotations: turning it half a turn about any of its own axes (q times i, j
or k) flips two axes and leaves its covariance as it was. Those four quaternions hold the same
four magnitudes in different places, so the encoder can always pick the one whose ``w`` is
the largest (:func:`canonical_rotations`): the dropped-component index is then 0 for every
Gaussian and costs nothing, where trained captures spend up to 2 bits a Gaussian on it. Nor
does the order of a Gaussian's axes mean anything: where that codes smaller
(:mod:`csgs_codec.decisions.axis_order`) the encoder sorts its scales, largest first, and
turns the rotation with them (:func:`canonical_orientations`).
"""

from __future__ import annotations

import numpy as np

SQRT2 = np.float32(np.sqrt(2.0))
#: Opacity logits beyond this change a render by less than 5e-5 per Gaussian.
OPACITY_LOGIT_LIMIT = 10.0
#: A Gaussian's axes are sorted only where its rotation's largest component stays at least
#: this large (or no smaller than it was): see :func:`canonical_orientations`.
SORTED_LARGEST_MIN = 0.6


def normalize_quaternions(rotations: np.ndarray) -> np.ndarray:
    """Unit quaternions (N, 4) float32 (w, x, y, z) from stored ones.

    A zero (or non-finite-norm) quaternion becomes the identity (1, 0, 0, 0), which is what a
    renderer that guards its normalisation draws.
    """
    q = rotations.astype(np.float64)
    norm = np.sqrt(np.sum(q * q, axis=1, keepdims=True))
    bad = ~(norm[:, 0] > 0) | ~np.isfinite(norm[:, 0])
    q = np.divide(q, norm, out=np.zeros_like(q), where=~bad[:, None])
    q[bad] = (1.0, 0.0, 0.0, 0.0)
    return q.astype(np.float32)


def canonical_rotations(rotations: np.ndarray) -> np.ndarray:
    """The (N, 4) float32 unit quaternions (w, x, y, z) of the same Gaussians whose ``w`` has
    the largest magnitude of the four components, and is positive.

    Of q, q*i = (-x, w, z, -y), q*j = (-y, -z, w, x) and q*k = (-z, y, -x, w), each the
    Gaussian turned half a turn about one of its axes (the same covariance for any scales),
    the one that moves the largest-magnitude component into ``w``; ties keep q. Input as for
    :func:`normalize_quaternions`.
    """
    q = normalize_quaternions(rotations).astype(np.float64)
    w, x, y, z = q.T
    turned = np.stack([q, np.stack([-x, w, z, -y], axis=1), np.stack([-y, -z, w, x], axis=1),
                       np.stack([-z, y, -x, w], axis=1)])
    largest = np.argmax(np.abs(q), axis=1)
    chosen = turned[largest, np.arange(len(q))]
    chosen *= np.where(chosen[:, :1] < 0, -1.0, 1.0)  # -q is the same rotation
    return chosen.astype(np.float32)


def canonical_orientations(rotations: np.ndarray, log_scales: np.ndarray,
                           min_largest: float = SORTED_LARGEST_MIN
                           ) -> tuple[np.ndarray, np.ndarray]:
    """The same Gaussians with their axes in a canonical order: scales largest first, and the
    rotation that goes with them in the form of :func:`canonical_rotations`.

    Relabelling a Gaussian's axes (and flipping one where the relabelling would mirror it)
    leaves its covariance as it was, so the order carries no information; sorted, the three
    log-scales code about log2(6) bits a Gaussian smaller. Ties keep their order.

    A relabelling turns the rotation by a quarter or a third of a turn, and may move it
    towards (1/2, 1/2, 1/2, 1/2), where the smallest-three form is least precise: its dropped
    component, the largest, is then 1/2, and an error e in each stored one moves it by up to
    3e (a cyclic relabelling takes the identity there, and at a coarse step it decoded as
    w = 0). A Gaussian whose sorted rotation's largest component would fall below
    ``min_largest`` and below its own rotation's keeps its axes as they are; at 0.6 that
    leaves 1-13% of the shared scenes' Gaussians unsorted that sorting would turn, and costs
    the SH-3 captures about 0.3 bits a Gaussian of the 1.9-3.0 that sorting saves (quality
    5's steps; the plan behind :mod:`csgs_codec.decisions.axis_order`).

    Args:
        rotations: (N, 4) quaternions (w, x, y, z), any norm (as :func:`normalize_quaternions`).
        log_scales: (N, 3) natural-log scales.
        min_largest: the guard above, in [0, 1] (0 sorts every Gaussian).

    Returns:
        (rotations (N, 4) float32, log_scales (N, 3) float32).
    """
    scales = np.asarray(log_scales, dtype=np.float32)
    order = np.argsort(-scales, axis=1, kind="stable")
    kept = canonical_rotations(rotations)
    matrices = _rotation_matrices(kept.astype(np.float64))
    relabelled = np.take_along_axis(matrices, order[:, None, :], axis=2)
    mirrored = np.linalg.det(relabelled) < 0
    relabelled[mirrored, :, 2] *= -1.0
    turned = canonical_rotations(_quaternions(relabelled))
    keep = turned[:, 0] < np.minimum(kept[:, 0], np.float32(min_largest))
    turned[keep] = kept[keep]
    sorted_scales = np.take_along_axis(scales, order, axis=1)
    sorted_scales[keep] = scales[keep]
    return turned, sorted_scales


def _rotation_matrices(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of (N, 4) unit quaternions (w, x, y, z)."""
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def _quaternions(m: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions (w, x, y, z) of (N, 3, 3) rotation matrices, each from the
    formula whose divisor is largest (the well-conditioned one)."""
    trace = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    # 4 * the squared magnitude of w, x, y, z in turn.
    four = np.stack([1 + trace, 1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2],
                     1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2],
                     1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2]], axis=1)
    pick = np.argmax(four, axis=1)
    big = 0.5 * np.sqrt(np.maximum(four[np.arange(len(m)), pick], 1e-300))
    zy, xz, yx = m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]
    xy, xz2, yz = m[:, 0, 1] + m[:, 1, 0], m[:, 0, 2] + m[:, 2, 0], m[:, 1, 2] + m[:, 2, 1]
    d = 4.0 * big
    options = np.stack([
        np.stack([big, zy / d, xz / d, yx / d], axis=1),
        np.stack([zy / d, big, xy / d, xz2 / d], axis=1),
        np.stack([xz / d, xy / d, big, yz / d], axis=1),
        np.stack([yx / d, xz2 / d, yz / d, big], axis=1),
    ])
    q = options[pick, np.arange(len(m))]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def quaternion_to_smallest_three(rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split quaternions (N, 4) into (largest (N,) uint8 in 0..3, rest (N, 3) float32 in [-1, 1]).

    ``rest`` holds the three other components of the normalized, sign-canonical quaternion in
    their original order, multiplied by sqrt(2).
    """
    q = normalize_quaternions(rotations).astype(np.float64)
    largest = np.argmax(np.abs(q), axis=1).astype(np.uint8)
    rows = np.arange(len(q))
    sign = np.where(q[rows, largest] < 0, -1.0, 1.0)
    q *= sign[:, None]
    keep = np.ones_like(q, dtype=bool)
    keep[rows, largest] = False
    rest = q[keep].reshape(-1, 3) * np.sqrt(2.0)
    return largest, np.clip(rest, -1.0, 1.0).astype(np.float32)


def smallest_three_to_quaternion(largest: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Inverse of :func:`quaternion_to_smallest_three`: (N, 4) float32 unit quaternions.

    Arithmetic (float32, in this order): c = rest / sqrt(2); m = 1 - (c0*c0 + c1*c1 + c2*c2);
    largest component = sqrt(max(m, 0)). Deterministic on every IEEE-754 machine.
    """
    largest = np.asarray(largest)
    c = rest.astype(np.float32) / SQRT2
    m = np.float32(1.0) - ((c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1]) + c[:, 2] * c[:, 2])
    big = np.sqrt(np.maximum(m, np.float32(0.0)))
    n = len(largest)
    out = np.empty((n, 4), np.float32)
    rows = np.arange(n)
    keep = np.ones((n, 4), dtype=bool)
    keep[rows, largest] = False
    out[keep] = c.reshape(-1)
    out[rows, largest] = big
    return out


def clamp_opacity_logits(opacity: np.ndarray, limit: float = OPACITY_LOGIT_LIMIT) -> np.ndarray:
    """Opacity logits (N,) clamped to [-limit, limit] (float32); beyond that renders agree."""
    return np.clip(opacity, -limit, limit).astype(np.float32)
