"""numba kernels of SSIM's forward and backward passes (float32 planes, CPU); importing this
module needs numba.

The definition is the one in :mod:`csgs_codec.metrics.ssim`. Filtering is separable (rows,
then columns; the backward pass takes the adjoints in the other order), parallel over
channels and bands of rows, with every sum taken in a fixed order, so the results do not
depend on the thread count.
"""

from __future__ import annotations

import numba
import numpy as np

from csgs_codec.render.numba_runtime import jit_kernel, one_launch_at_a_time

#: Output rows a forward job filters: it row-filters _BAND + k - 1 input rows once and
#: keeps them in a buffer of that many rows (about 84 KB at 512 pixels wide) for the column
#: pass, so no image-sized intermediate is written (fresh pages for one cost more than the
#: filtering on the project's CPU box: 17-24 ms against 5 ms a 512x384 forward).
_BAND = 32


@jit_kernel()
def _filter_band(a: np.ndarray, b: np.ndarray, taps: np.ndarray, which: int, c: int,
                 first: int, last: int, out: np.ndarray) -> None:
    """Output rows ``first``..``last`` - 1 of channel ``c`` of statistic ``which`` (a, b,
    a^2, b^2, a*b; float32 products) into ``out`` [5, C, H', W']."""
    k = taps.shape[0]
    out_w = out.shape[3]
    source = b if which in (1, 3) else a
    other = b if which == 4 else source
    filtered = np.zeros((last - first + k - 1, out_w), np.float32)
    line = np.empty(a.shape[2], np.float32)
    for s in range(filtered.shape[0]):
        for j in range(line.shape[0]):
            line[j] = (source[c, first + s, j] if which < 2
                       else source[c, first + s, j] * other[c, first + s, j])
        for t in range(k):
            w = taps[t]
            for j in range(out_w):
                filtered[s, j] += w * line[j + t]
    column = np.empty(out_w, np.float32)
    for i in range(first, last):
        for j in range(out_w):
            column[j] = 0
        for t in range(k):
            w = taps[t]
            for j in range(out_w):
                column[j] += w * filtered[i - first + t, j]
        for j in range(out_w):
            out[which, c, i, j] = column[j]


@one_launch_at_a_time
@jit_kernel(parallel=True)
def window_statistics(a: np.ndarray, b: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """[5, C, H', W'] window means of a, b, a^2, b^2 and a*b for [C, H, W] float32 planes
    ('valid' filtering, H' = H - k + 1, W' = W - k + 1).

    Separable: each row is filtered, then each column, every sum from zero in tap order in
    float32. Jobs are (statistic, channel, band of :data:`_BAND` output rows).
    """
    channels, height, width = a.shape
    k = taps.shape[0]
    out_h, out_w = height - k + 1, width - k + 1
    bands = (out_h + _BAND - 1) // _BAND
    out = np.empty((5, channels, out_h, out_w), np.float32)
    for job in numba.prange(5 * channels * bands):
        which, rest = job // (channels * bands), job % (channels * bands)
        c, band = rest // bands, rest % bands
        _filter_band(a, b, taps, which, c, band * _BAND, min(out_h, band * _BAND + _BAND),
                     out)
    return out


@one_launch_at_a_time
@jit_kernel(parallel=True)
def score_and_slopes(stats: np.ndarray, c1: float, c2: float,
                     slopes: np.ndarray) -> float:
    """Sum of the SSIM map over [C, H', W'] from ``stats`` (:func:`window_statistics`), in
    float64; ``slopes`` [3, C, H', W'] receives its derivatives with respect to the window
    means of a, a^2 and a*b."""
    _, channels, out_h, out_w = stats.shape
    rows = np.zeros(channels * out_h, np.float64)
    for job in numba.prange(channels * out_h):
        c, i = job // out_h, job % out_h
        # The row's scores first, then their sum in order: a loop with the running sum in
        # it cannot be vectorised (float addition is not associative), one without can.
        scores = np.empty(out_w, np.float64)
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
            scores[j] = score
            slopes[0, c, i, j] = (2 * mu_b * (num2 - num1) / den
                                  - score * 2 * mu_a * (1 / den1 - 1 / den2))
            slopes[1, c, i, j] = -score / den2
            slopes[2, c, i, j] = 2 * num1 / den
        total = 0.0
        for j in range(out_w):
            total += scores[j]
        rows[job] = total
    return rows.sum()


@one_launch_at_a_time
@jit_kernel(parallel=True)
def gradient_of_a(a: np.ndarray, b: np.ndarray, slopes: np.ndarray,
                  taps: np.ndarray) -> np.ndarray:
    """[C, H, W] derivative of the SSIM map's sum with respect to a (see module notes).

    Per image row: the adjoint of the column filter, then of the row filter, on the three
    slope maps (sums from zero in tap order, float32), combined as s_mu + 2 a s_sq + b s_ab.
    Jobs are (channel, row); nothing image-sized is written but the result.
    """
    channels, height, width = a.shape
    k = taps.shape[0]
    in_h, in_w = slopes.shape[2], slopes.shape[3]
    out = np.empty((channels, height, width), np.float32)
    for job in numba.prange(channels * height):
        c, r = job // height, job % height
        spread = np.zeros((3, width), np.float32)
        column = np.empty(in_w, np.float32)
        for q in range(3):
            column[:] = 0
            # Taps t with 0 <= r - t < in_h, in increasing order.
            for t in range(max(0, r - in_h + 1), min(k, r + 1)):
                w = taps[t]
                for j in range(in_w):
                    column[j] += w * slopes[q, c, r - t, j]
            for t in range(k):
                w = taps[t]
                for j in range(in_w):
                    spread[q, j + t] += w * column[j]
        two = np.float32(2.0)
        for x in range(width):
            out[c, r, x] = (spread[0, x] + two * a[c, r, x] * spread[1, x]
                            + b[c, r, x] * spread[2, x])
    return out
