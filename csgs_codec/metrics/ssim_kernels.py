"""numba kernels of SSIM's forward and backward passes (float32 planes, CPU); importing this
module needs numba.

The definition is the one in :mod:`csgs_codec.metrics.ssim`. Filtering is separable (rows,
then columns), parallel over planes and rows, with every sum taken in a fixed order, so the
results do not depend on the thread count.
"""

from __future__ import annotations

import numba
import numpy as np

from csgs_codec.render import numba_kernels  # noqa: F401  (selects the threading layer)


@numba.njit(parallel=True, cache=True)
def _filter_rows(planes: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """[P, H, W] -> [P, H, W - k + 1]: 'valid' filtering along each row."""
    p_count, height, width = planes.shape
    k = taps.shape[0]
    out_w = width - k + 1
    out = np.zeros((p_count, height, out_w), np.float32)
    for job in numba.prange(p_count * height):
        p, r = job // height, job % height
        for t in range(k):
            w = taps[t]
            for j in range(out_w):
                out[p, r, j] += w * planes[p, r, j + t]
    return out


@numba.njit(parallel=True, cache=True)
def _filter_columns(planes: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """[P, H, W] -> [P, H - k + 1, W]: 'valid' filtering along each column."""
    p_count, height, width = planes.shape
    k = taps.shape[0]
    out_h = height - k + 1
    out = np.zeros((p_count, out_h, width), np.float32)
    for job in numba.prange(p_count * out_h):
        p, i = job // out_h, job % out_h
        for t in range(k):
            w = taps[t]
            for j in range(width):
                out[p, i, j] += w * planes[p, i + t, j]
    return out


@numba.njit(parallel=True, cache=True)
def _spread_rows(planes: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Transpose of :func:`_filter_rows`: [P, H, W'] -> [P, H, W' + k - 1]."""
    p_count, height, in_w = planes.shape
    k = taps.shape[0]
    out = np.zeros((p_count, height, in_w + k - 1), np.float32)
    for job in numba.prange(p_count * height):
        p, r = job // height, job % height
        for t in range(k):
            w = taps[t]
            for j in range(in_w):
                out[p, r, j + t] += w * planes[p, r, j]
    return out


@numba.njit(parallel=True, cache=True)
def _spread_columns(planes: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Transpose of :func:`_filter_columns`: [P, H', W] -> [P, H' + k - 1, W]."""
    p_count, in_h, width = planes.shape
    k = taps.shape[0]
    out_h = in_h + k - 1
    out = np.zeros((p_count, out_h, width), np.float32)
    for job in numba.prange(p_count * out_h):
        p, r = job // out_h, job % out_h
        # Taps t with 0 <= r - t < in_h, in increasing order (no test in the loop, which
        # kept the inner loop from vectorising: 3.7x the time of _filter_columns per plane).
        for t in range(max(0, r - in_h + 1), min(k, r + 1)):
            w = taps[t]
            for j in range(width):
                out[p, r, j] += w * planes[p, r - t, j]
    return out


def window_statistics(a: np.ndarray, b: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """[5, C, H', W'] window means of a, b, a^2, b^2 and a*b for [C, H, W] float32 planes.

    Plain numpy around the compiled filters: compiled whole, this stacking took numba 12 s
    on a cold cache (every fresh test worker), against milliseconds of run time.
    """
    stacked = np.concatenate([a, b, a * a, b * b, a * b]).astype(np.float32, copy=False)
    filtered = _filter_columns(_filter_rows(stacked, taps), taps)
    return filtered.reshape((5, a.shape[0]) + filtered.shape[1:])


@numba.njit(parallel=True, cache=True)
def score_and_slopes(stats: np.ndarray, c1: float, c2: float,
                     slopes: np.ndarray) -> float:
    """Sum of the SSIM map over [C, H', W'] from ``stats`` (:func:`window_statistics`), in
    float64; ``slopes`` [3, C, H', W'] receives its derivatives with respect to the window
    means of a, a^2 and a*b."""
    _, channels, out_h, out_w = stats.shape
    rows = np.zeros(channels * out_h, np.float64)
    for job in numba.prange(channels * out_h):
        c, i = job // out_h, job % out_h
        total = 0.0
        for j in range(out_w):
            mu_a, mu_b = stats[0, c, i, j], stats[1, c, i, j]
            var_a = stats[2, c, i, j] - mu_a * mu_a
            var_b = stats[3, c, i, j] - mu_b * mu_b
            cov = stats[4, c, i, j] - mu_a * mu_b
            num1 = 2 * mu_a * mu_b + c1
            num2 = 2 * cov + c2
            den1 = mu_a * mu_a + mu_b * mu_b + c1
            den2 = var_a + var_b + c2
            den = den1 * den2
            score = num1 * num2 / den
            total += score
            slopes[0, c, i, j] = (2 * mu_b * (num2 - num1) / den
                                  - score * 2 * mu_a * (1 / den1 - 1 / den2))
            slopes[1, c, i, j] = -score / den2
            slopes[2, c, i, j] = 2 * num1 / den
        rows[job] = total
    return rows.sum()


def gradient_of_a(a: np.ndarray, b: np.ndarray, slopes: np.ndarray,
                  taps: np.ndarray) -> np.ndarray:
    """[C, H, W] derivative of the SSIM map's sum with respect to a (see module notes);
    numpy around the compiled spreads, as :func:`window_statistics`."""
    channels = a.shape[0]
    flat = np.ascontiguousarray(slopes.reshape((3 * channels,) + slopes.shape[2:]))
    spread = _spread_rows(_spread_columns(flat, taps), taps)
    return (spread[:channels] + 2 * a * spread[channels:2 * channels]
            + b * spread[2 * channels:])
