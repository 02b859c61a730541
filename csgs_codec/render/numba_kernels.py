"""numba kernels of the fast forward rasterizer; importing this module needs numba.

The compositing rule is the one in :mod:`csgs_codec.render.composite_torch`, evaluated in
float32 pixel by pixel with an early exit per pixel (:mod:`csgs_codec.render.numba_pixel`);
binning, blend weights, per-pixel blend records and the per-Gaussian sums of slot gradients
are here, compositing and its gradients in :mod:`csgs_codec.render.numba_composite`. Tiles
run in parallel.

The kernels Python calls take turns across threads and run on the threading layer that
:mod:`csgs_codec.render.numba_runtime` selects.
"""

from __future__ import annotations

import numba
import numpy as np

# Compositing and its replay for gradients live in numba_composite; re-exported here, the
# module every caller takes the kernels from.
from csgs_codec.render.numba_composite import (  # noqa: F401
    composite_tiles,
    composite_tiles_backward,
)
from csgs_codec.render.numba_pixel import ALPHA_THRESHOLD32 as _ALPHA_THRESHOLD
from csgs_codec.render.numba_pixel import HALF as _HALF
from csgs_codec.render.numba_pixel import ONE as _ONE
from csgs_codec.render.numba_pixel import POWER_MARGIN as _POWER_MARGIN
from csgs_codec.render.numba_pixel import T_STOP as _T_STOP
from csgs_codec.render.numba_pixel import alpha_at as _alpha_at
from csgs_codec.render.numba_pixel import pack_tile as _pack_tile
from csgs_codec.render.numba_runtime import jit_kernel, one_launch_at_a_time

#: Relative slack of the tile test (:func:`_row_spans`) on the float32 exponent, about 170
#: float32 ulps of the exponent's largest term: a Gaussian leaves a tile's list only when no
#: pixel of the tile can reach the alpha threshold whatever the rounding of the per-pixel
#: arithmetic.
_CULL_SLACK = 1e-5


@jit_kernel(parallel=True)
def _row_spans(rects: np.ndarray, order: np.ndarray, row_start: np.ndarray, tile_size: int,
               width: int, height: int, means2d: np.ndarray, conics: np.ndarray,
               opacities: np.ndarray) -> np.ndarray:
    """[row_start[-1], 2] int64: for the i-th Gaussian of ``order`` and each tile row of its
    box (from ``row_start[i]``), the half-open range of tile columns where it can reach the
    alpha threshold at some pixel centre (an empty range where it cannot).

    Where a Gaussian reaches the threshold, -0.5 (a dx^2 + 2 b dx dy + c dy^2) >= T (T the
    exponent below which :func:`_alpha_at` gives alpha 0, taken lower by
    :data:`_CULL_SLACK` of the terms' size over the box), an ellipse: its points in a row of
    tiles span an interval of x, which is found in float64 from where the ellipse's
    leftmost and rightmost points lie, or the row's edges when those fall outside it. A
    tile outside the interval changes no pixel if dropped: compositing skips the Gaussian
    at every pixel there.
    """
    spans = np.empty((row_start[-1], 2), np.int64)
    for i in numba.prange(order.shape[0]):
        g = order[i]
        tx0, tx1, ty0, ty1 = rects[g, 0], rects[g, 1], rects[g, 2], rects[g, 3]
        a = np.float64(conics[g, 0])
        b = np.float64(conics[g, 1])
        c = np.float64(conics[g, 2])
        det = a * c - b * b
        mx = np.float64(means2d[g, 0])
        my = np.float64(means2d[g, 1])
        threshold = np.float64(np.log(_ALPHA_THRESHOLD / opacities[g]) - _POWER_MARGIN)
        span_x = max(abs(tx0 * tile_size - mx), abs(tx1 * tile_size - mx)) + 1.0
        span_y = max(abs(ty0 * tile_size - my), abs(ty1 * tile_size - my)) + 1.0
        size = 0.5 * a * span_x * span_x + 0.5 * c * span_y * span_y + abs(b) * span_x * span_y
        bound = -2.0 * (threshold - _CULL_SLACK * (size + abs(threshold) + 1.0))
        exact = a > 0.0 and c > 0.0 and det > 0.0 and bound > 0.0 and np.isfinite(size)
        if exact:
            # The ellipse a x^2 + 2 b x y + c y^2 <= bound around the mean: x within
            # +-x_far, reached at y = -+b x_far / c; y within +-y_far.
            x_far = np.sqrt(bound * c / det)
            y_far = np.sqrt(bound * a / det)
            y_right = -b * x_far / c
        for r in range(ty1 - ty0):
            k = row_start[i] + r
            if not exact:
                spans[k, 0] = tx0
                spans[k, 1] = tx1
                continue
            ty = ty0 + r
            v0 = max(ty * tile_size + 0.5 - my, -y_far)
            v1 = min(min(ty * tile_size + tile_size, height) - 0.5 - my, y_far)
            if v0 > v1:
                spans[k, 0] = tx0
                spans[k, 1] = tx0
                continue
            y = min(max(y_right, v0), v1)
            right = (-b * y + np.sqrt(max(a * bound - det * y * y, 0.0))) / a
            y = min(max(-y_right, v0), v1)
            left = (-b * y - np.sqrt(max(a * bound - det * y * y, 0.0))) / a
            # Tile columns whose pixel centres (x + 0.5 - mean) can fall in [left, right].
            lo = np.ceil((mx + left + 0.5) / tile_size) - 1.0
            hi = np.floor((mx + right - 0.5) / tile_size) + 1.0
            lo_tile = tx0 if not lo > tx0 else (tx1 if lo > tx1 else np.int64(lo))
            hi_tile = tx1 if not hi < tx1 else (tx0 if hi < tx0 else np.int64(hi))
            spans[k, 0] = lo_tile
            spans[k, 1] = max(hi_tile, lo_tile)
    return spans


@one_launch_at_a_time
@jit_kernel()
def bin_tiles(rects: np.ndarray, order: np.ndarray, n_tiles: int, tiles_x: int,
              tile_size: int, width: int, height: int, means2d: np.ndarray,
              conics: np.ndarray, opacities: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Counting-sort binning: (offsets [T + 1] int64, gaussian ids [I] int64), near to far.

    ``rects`` is [N, 4] int64 (tx0, tx1, ty0, ty1), each Gaussian's box of tiles; ``order``
    is [M] int64, near to far. A tile of the box keeps the Gaussian only when it can reach
    the alpha threshold at one of the tile's pixels (:func:`_row_spans`, from float32
    ``means2d`` [N, 2], ``conics`` [N, 3], ``opacities`` [N] as compositing takes them):
    the box of an ellipse also covers tiles its corners miss (30-60% of the box's tiles on
    real captures), which every pixel there would test and skip.
    """
    row_start = np.zeros(order.shape[0] + 1, np.int64)
    for i in range(order.shape[0]):
        g = order[i]
        row_start[i + 1] = row_start[i] + (rects[g, 3] - rects[g, 2])
    spans = _row_spans(rects, order, row_start, tile_size, width, height, means2d, conics,
                       opacities)
    offsets = np.zeros(n_tiles + 1, np.int64)
    for i in range(order.shape[0]):
        g = order[i]
        for r in range(rects[g, 3] - rects[g, 2]):
            row = (rects[g, 2] + r) * tiles_x + 1
            k = row_start[i] + r
            for tx in range(spans[k, 0], spans[k, 1]):
                offsets[row + tx] += 1
    for t in range(n_tiles):
        offsets[t + 1] += offsets[t]
    cursor = offsets[:-1].copy()
    ids = np.empty(offsets[n_tiles], np.int64)
    for i in range(order.shape[0]):
        g = order[i]
        for r in range(rects[g, 3] - rects[g, 2]):
            row = (rects[g, 2] + r) * tiles_x
            k = row_start[i] + r
            for tx in range(spans[k, 0], spans[k, 1]):
                ids[cursor[row + tx]] = g
                cursor[row + tx] += 1
    return offsets, ids


@one_launch_at_a_time
@jit_kernel(parallel=True)
def blend_weight_slots(offsets: np.ndarray, ids: np.ndarray, means2d: np.ndarray,
                       conics: np.ndarray, opacities: np.ndarray, width: int, height: int,
                       tile_size: int, tiles_x: int, weight_sq: np.ndarray,
                       weight_sum: np.ndarray) -> None:
    """Blending weights w = alpha * T of every (tile, Gaussian) slot, summed over the tile's
    pixels with the compositing rule of :func:`composite_tiles`.

    ``weight_sq`` and ``weight_sum`` are [I] float64, one entry per slot of ``ids`` (zeroed
    by the caller): each slot belongs to one tile, so tiles write disjoint entries and run
    in parallel without races; the caller sums slots per Gaussian.
    """
    n_tiles = offsets.shape[0] - 1
    for t in numba.prange(n_tiles):
        start = offsets[t]
        count = offsets[t + 1] - start
        if count == 0:
            continue
        packed = _pack_tile(ids, start, count, means2d, conics, opacities)
        x0 = (t % tiles_x) * tile_size
        y0 = (t // tiles_x) * tile_size
        for py in range(y0, min(y0 + tile_size, height)):
            pyc = np.float32(py) + _HALF
            for px in range(x0, min(x0 + tile_size, width)):
                pxc = np.float32(px) + _HALF
                trans = _ONE
                for k in range(count):
                    alpha, _, _, _ = _alpha_at(packed, k, pxc, pyc)
                    if alpha == 0:
                        continue
                    after = trans * (_ONE - alpha)
                    if after < _T_STOP:
                        break
                    weight = np.float64(alpha * trans)
                    weight_sq[start + k] += weight * weight
                    weight_sum[start + k] += weight
                    trans = after


@one_launch_at_a_time
@jit_kernel()
def sum_slots(ids: np.ndarray, slot_grads: np.ndarray, n: int) -> np.ndarray:
    """[n, K] float64 sums of the [I, K] slot rows per Gaussian ``ids`` [I], in slot order
    (one thread, so the sums are the same on every run)."""
    total = np.zeros((n, slot_grads.shape[1]), np.float64)
    for i in range(ids.shape[0]):
        g = ids[i]
        for j in range(slot_grads.shape[1]):
            total[g, j] += slot_grads[i, j]
    return total


@one_launch_at_a_time
@jit_kernel(parallel=True)
def record_blend(offsets: np.ndarray, ids: np.ndarray, means2d: np.ndarray,
                 conics: np.ndarray, opacities: np.ndarray, width: int, height: int,
                 tile_size: int, tiles_x: int, starts: np.ndarray, blend_ids: np.ndarray,
                 blend_weights: np.ndarray, counts: np.ndarray) -> None:
    """The (Gaussian, weight) pairs :func:`composite_tiles` adds to each pixel, in its order.

    Pixel p (row-major) gets its j-th pair at ``starts[p] + j`` of ``blend_ids`` (int32) and
    ``blend_weights`` (float32, the w = alpha T the compositing multiplies each value by),
    and ``counts[p]`` (int32) pairs; ``starts`` [H W + 1] int64 must leave at least as many
    entries per pixel as its tile slots walked (``walked`` of :func:`composite_tiles`).
    """
    n_tiles = offsets.shape[0] - 1
    for t in numba.prange(n_tiles):
        start = offsets[t]
        count = offsets[t + 1] - start
        if count == 0:
            continue
        packed = _pack_tile(ids, start, count, means2d, conics, opacities)
        x0 = (t % tiles_x) * tile_size
        y0 = (t // tiles_x) * tile_size
        for py in range(y0, min(y0 + tile_size, height)):
            pyc = np.float32(py) + _HALF
            for px in range(x0, min(x0 + tile_size, width)):
                pxc = np.float32(px) + _HALF
                p = py * width + px
                at = starts[p]
                trans = _ONE
                for k in range(count):
                    alpha, _, _, _ = _alpha_at(packed, k, pxc, pyc)
                    if alpha == 0:
                        continue
                    after = trans * (_ONE - alpha)
                    if after < _T_STOP:
                        break
                    blend_ids[at] = ids[start + k]
                    blend_weights[at] = alpha * trans
                    at += 1
                    trans = after
                counts[p] = at - starts[p]


@one_launch_at_a_time
@jit_kernel(parallel=True)
def replay_blend(starts: np.ndarray, counts: np.ndarray, blend_ids: np.ndarray,
                 blend_weights: np.ndarray, values: np.ndarray, out: np.ndarray) -> None:
    """Accumulate ``values`` [N, C] float32 into ``out`` [P, C] float32 (zeroed) with the
    pairs :func:`record_blend` recorded, in their order: the same float32 sums
    :func:`composite_tiles` forms, so a replay with the values it composited gives its
    ``out`` bit for bit."""
    channels = values.shape[1]
    for p in numba.prange(out.shape[0]):
        for j in range(counts[p]):
            e = starts[p] + j
            g = blend_ids[e]
            weight = blend_weights[e]
            for ch in range(channels):
                out[p, ch] += weight * values[g, ch]
