"""numba kernels that composite tiles and replay them for gradients, a pixel row at a time;
importing this module needs numba.

The rule is the per-pixel walk of :mod:`csgs_codec.render.numba_pixel` (each pixel goes
through its tile's list near to far in float32 and stops once opaque); these kernels give
what that walk gives, bit for bit, with less work:

* Per pixel row, each Gaussian of the tile's list is tried only at the columns where it can
  reach the alpha threshold (:func:`row_columns`, an exact ellipse bound widened past any
  float32 rounding), not at every pixel of the tile: on a 512x384 training view of
  benchmarks/train_speed.py 3,212,544 pair tests went to 870,548, against 870,111 pairs
  that draw (the per-pair work, exp() and the sums, is now most of the time).
* A row's pixels are its lanes: the kernel takes the list once per row, Gaussian by
  Gaussian, and each lane keeps its own transmittance and running sums, so every pixel meets
  its Gaussians in the walk's order and every sum is formed in the walk's order (a slot's
  gradient sums its pixels row by row, left to right, as the walk does).
* The tiles that hold Gaussians are dealt to the threads largest first
  (:func:`balanced_tiles`); a scene seldom fills the image evenly, and numba hands each
  thread one contiguous share of a parallel loop.

The kernels Python calls take turns across threads and run on the threading layer that
:mod:`csgs_codec.render.numba_runtime` selects.
"""

from __future__ import annotations

import numba
import numpy as np

from csgs_codec.render.numba_pixel import HALF, MAX_ALPHA32, ONE, T_STOP, alpha_at, pack_tile
from csgs_codec.render.numba_runtime import compile_safely, jit_kernel, one_launch_at_a_time

#: Relative slack of the row test (:func:`row_columns`) on the float32 exponent, as the tile
#: test of :func:`csgs_codec.render.numba_kernels.bin_tiles` takes it.
ROW_SLACK = 1e-5
#: Pixels added on each side of a row's column range, past the float64 rounding of its ends.
ROW_MARGIN = 1e-3


@jit_kernel()
def row_columns(packed: np.ndarray, count: int, x0: int, cols: int, py: int,
                lows: np.ndarray, highs: np.ndarray) -> None:
    """For pixel row ``py`` of a tile whose columns are x0..x0 + cols - 1: the columns
    ``lows[k]``..``highs[k]`` - 1 (relative to x0, int64) outside which packed Gaussian k
    (:func:`~csgs_codec.render.numba_pixel.pack_tile`) has alpha 0 at every pixel centre by
    :func:`~csgs_codec.render.numba_pixel.alpha_at`.

    A pixel draws only where the float32 exponent -0.5 (a dx^2 + c dy^2) - b dx dy reaches
    the packed threshold T. The exact exponent differs from the float32 one by less than
    :data:`ROW_SLACK` of the terms' size over the row (plus |T| + 1), so the pixels lie in
    the ellipse a dx^2 + 2 b dx dy + c dy^2 <= -2 (T - slack): on the row's dy an interval
    of dx, found in float64. Gaussians whose conic is not positive definite, or whose
    numbers are not finite, keep the whole row.
    """
    y_offset = np.float64(py) + 0.5
    left_edge = np.float64(x0)
    right_edge = np.float64(x0 + cols)
    for k in range(count):
        mx = np.float64(packed[k, 0])
        dy = y_offset - np.float64(packed[k, 1])
        a = np.float64(packed[k, 2])
        b = np.float64(packed[k, 3])
        c = np.float64(packed[k, 4])
        threshold = np.float64(packed[k, 6])
        det = a * c - b * b
        span_x = max(abs(left_edge - mx), abs(right_edge - mx)) + 1.0
        span_y = abs(dy) + 1.0
        size = 0.5 * a * span_x * span_x + 0.5 * c * span_y * span_y + abs(b) * span_x * span_y
        bound = -2.0 * (threshold - ROW_SLACK * (size + abs(threshold) + 1.0))
        if not (a > 0.0 and c > 0.0 and det > 0.0 and bound > 0.0 and np.isfinite(size)
                and np.isfinite(mx) and np.isfinite(dy)):
            lows[k] = 0
            highs[k] = cols
            continue
        disc = a * bound - det * dy * dy
        if disc < 0.0:
            lows[k] = 0
            highs[k] = 0
            continue
        root = np.sqrt(disc)
        # Columns j whose centre offset x0 + j + 0.5 - mx lies in [left, right].
        first = np.ceil(mx + (-b * dy - root) / a - 0.5 - left_edge - ROW_MARGIN)
        last = np.floor(mx + (-b * dy + root) / a - 0.5 - left_edge + ROW_MARGIN)
        lo = 0 if not first > 0.0 else (cols if first > cols else np.int64(first))
        hi = 0 if not last >= 0.0 else (cols if last >= cols else np.int64(last) + 1)
        lows[k] = lo
        highs[k] = max(hi, lo)


@compile_safely
@jit_kernel()
def balanced_tiles(offsets: np.ndarray, threads: int) -> np.ndarray:
    """[J] int64 the tiles with Gaussians (list lengths from ``offsets`` [T + 1]), dealt
    longest list first into ``threads`` contiguous shares, to and fro (share 0, 1, ..., the
    last, the last, ..., 0, 0, ...) so the shares' total lengths come out about equal: the
    order for a parallel loop that numba splits into one share per thread."""
    lengths = offsets[1:] - offsets[:-1]
    full = np.nonzero(lengths > 0)[0]
    ranked = full[np.argsort(-lengths[full], kind="mergesort")]
    n = ranked.shape[0]
    threads = max(1, min(threads, n))
    share_of = np.empty(n, np.int64)
    sizes = np.zeros(threads, np.int64)
    for i in range(n):
        turn, place = i // threads, i % threads
        share = place if turn % 2 == 0 else threads - 1 - place
        share_of[i] = share
        sizes[share] += 1
    cursor = np.zeros(threads, np.int64)
    for share in range(1, threads):
        cursor[share] = cursor[share - 1] + sizes[share - 1]
    jobs = np.empty(n, np.int64)
    for i in range(n):
        jobs[cursor[share_of[i]]] = ranked[i]
        cursor[share_of[i]] += 1
    return jobs


def composite_tiles(offsets: np.ndarray, ids: np.ndarray, means2d: np.ndarray,
                    conics: np.ndarray, opacities: np.ndarray, values: np.ndarray,
                    width: int, height: int, tile_size: int, tiles_x: int,
                    out: np.ndarray, transmittance: np.ndarray, walked: np.ndarray) -> None:
    """Composite every tile into ``out`` [H, W, C] and ``transmittance`` [H, W] (float32).

    ``out`` must start at zero and ``transmittance`` at one; per-Gaussian inputs are float32:
    means2d [N, 2], conics [N, 3], opacities [N], values [N, C]; ``offsets`` [T + 1] and
    ``ids`` [I] are the tile lists of :func:`~csgs_codec.render.numba_kernels.bin_tiles`.
    ``walked`` [H, W] int32 receives how many of its tile's Gaussians each pixel went through
    before it stopped (the backward pass replays exactly those).
    """
    _composite_rows(balanced_tiles(offsets, numba.get_num_threads()), offsets, ids, means2d,
                    conics, opacities, values, width, height, tile_size, tiles_x, out,
                    transmittance, walked)


@one_launch_at_a_time
@jit_kernel(parallel=True)
def _composite_rows(jobs, offsets, ids, means2d, conics, opacities, values, width, height,
                    tile_size, tiles_x, out, transmittance, walked):
    """:func:`composite_tiles` over the tiles ``jobs`` (:func:`balanced_tiles`)."""
    channels = values.shape[1]
    for job in numba.prange(jobs.shape[0]):
        t = jobs[job]
        start = offsets[t]
        count = offsets[t + 1] - start
        packed = pack_tile(ids, start, count, means2d, conics, opacities)
        x0 = (t % tiles_x) * tile_size
        y0 = (t // tiles_x) * tile_size
        cols = min(x0 + tile_size, width) - x0
        lows = np.empty(count, np.int64)
        highs = np.empty(count, np.int64)
        trans = np.empty(cols, np.float32)
        stop = np.empty(cols, np.int64)
        acc = np.empty((cols, channels), np.float32)
        colour = np.empty(channels, np.float32)
        for py in range(y0, min(y0 + tile_size, height)):
            pyc = np.float32(py) + HALF
            row_columns(packed, count, x0, cols, py, lows, highs)
            for j in range(cols):
                trans[j] = ONE
                stop[j] = count
                for ch in range(channels):
                    acc[j, ch] = np.float32(0.0)
            still_open = cols
            for k in range(count):
                lo, hi = lows[k], highs[k]
                if lo >= hi:
                    continue
                g = ids[start + k]
                for ch in range(channels):
                    colour[ch] = values[g, ch]
                for j in range(lo, hi):
                    if stop[j] != count:
                        continue
                    alpha, _, _, _ = alpha_at(packed, k, np.float32(x0 + j) + HALF, pyc)
                    if alpha == 0:
                        continue
                    after = trans[j] * (ONE - alpha)
                    if after < T_STOP:
                        stop[j] = k
                        still_open -= 1
                        continue
                    weight = alpha * trans[j]
                    for ch in range(channels):
                        acc[j, ch] += weight * colour[ch]
                    trans[j] = after
                if still_open == 0:
                    break
            for j in range(cols):
                for ch in range(channels):
                    out[py, x0 + j, ch] = acc[j, ch]
                transmittance[py, x0 + j] = trans[j]
                walked[py, x0 + j] = stop[j]


def composite_tiles_backward(offsets: np.ndarray, ids: np.ndarray, means2d: np.ndarray,
                             conics: np.ndarray, opacities: np.ndarray, values: np.ndarray,
                             width: int, height: int, tile_size: int, tiles_x: int,
                             out: np.ndarray, transmittance: np.ndarray, walked: np.ndarray,
                             grad_out: np.ndarray, grad_transmittance: np.ndarray,
                             slot_grads: np.ndarray) -> None:
    """Gradients of :func:`composite_tiles` for every (tile, Gaussian) slot of ``ids``.

    Each pixel replays its forward walk (same float32 operations in the same order, so the
    same pairs contribute) with ``out``, ``transmittance`` and ``walked`` from the forward
    pass. For pair i of a pixel with weight w_i = alpha_i T_i and S_i the accumulated value
    of the pairs behind it (``out`` minus the running sum up to i):

        dL/dalpha_i = sum_c g_c (T_i v_ic - S_ic / (1 - alpha_i)) - g_T T_final / (1 - alpha_i)
        dL/dv_ic = g_c w_i

    and the chain rule through alpha = min(0.99, opacity exp(power)) gives the mean, conic
    and opacity terms. ``slot_grads`` [I, 6 + C] float32 (zeroed by the caller) receives
    (mean x, mean y, conic a, b, c, opacity, values...), each slot's sum over its tile's
    pixels row by row, left to right; slots belong to one tile each, so tiles run in
    parallel without races and the caller sums slots per Gaussian.
    """
    _replay_rows(balanced_tiles(offsets, numba.get_num_threads()), offsets, ids, means2d,
                 conics, opacities, values, width, height, tile_size, tiles_x, out,
                 transmittance, walked, grad_out, grad_transmittance, slot_grads)


@one_launch_at_a_time
@jit_kernel(parallel=True)
def _replay_rows(jobs, offsets, ids, means2d, conics, opacities, values, width, height,
                 tile_size, tiles_x, out, transmittance, walked, grad_out, grad_transmittance,
                 slot_grads):
    """:func:`composite_tiles_backward` over the tiles ``jobs`` (:func:`balanced_tiles`)."""
    channels = values.shape[1]
    for job in numba.prange(jobs.shape[0]):
        t = jobs[job]
        start = offsets[t]
        count = offsets[t + 1] - start
        packed = pack_tile(ids, start, count, means2d, conics, opacities)
        x0 = (t % tiles_x) * tile_size
        y0 = (t // tiles_x) * tile_size
        cols = min(x0 + tile_size, width) - x0
        lows = np.empty(count, np.int64)
        highs = np.empty(count, np.int64)
        trans = np.empty(cols, np.float32)
        stop = np.empty(cols, np.int64)
        running = np.empty((cols, channels), np.float32)
        g_values = np.empty(channels, np.float32)
        colour = np.empty(channels, np.float32)
        for py in range(y0, min(y0 + tile_size, height)):
            deepest = 0
            for j in range(cols):
                stop[j] = walked[py, x0 + j]
                deepest = max(deepest, stop[j])
                trans[j] = ONE
                for ch in range(channels):
                    running[j, ch] = np.float32(0.0)
            if deepest == 0:
                continue
            pyc = np.float32(py) + HALF
            row_columns(packed, count, x0, cols, py, lows, highs)
            for k in range(deepest):
                lo, hi = lows[k], highs[k]
                if lo >= hi:
                    continue
                g = ids[start + k]
                slot = start + k
                # The slot's sums in registers across the row's lanes: the same additions in
                # the same order as adding to slot_grads pixel by pixel.
                g_mx, g_my = slot_grads[slot, 0], slot_grads[slot, 1]
                g_a, g_b, g_c = slot_grads[slot, 2], slot_grads[slot, 3], slot_grads[slot, 4]
                g_op = slot_grads[slot, 5]
                for ch in range(channels):
                    g_values[ch] = slot_grads[slot, 6 + ch]
                    colour[ch] = values[g, ch]
                a_k, b_k, c_k, opacity_k = packed[k, 2], packed[k, 3], packed[k, 4], packed[k, 5]
                for j in range(lo, hi):
                    if k >= stop[j]:
                        continue
                    px = x0 + j
                    alpha, falloff, dx, dy = alpha_at(packed, k, np.float32(px) + HALF, pyc)
                    if alpha == 0:
                        continue
                    raw = opacity_k * falloff
                    keep = ONE - alpha
                    before = trans[j]
                    weight = alpha * before
                    grad_alpha = -grad_transmittance[py, px] * transmittance[py, px] / keep
                    for ch in range(channels):
                        value = colour[ch]
                        running[j, ch] += weight * value
                        behind = out[py, px, ch] - running[j, ch]
                        grad_ch = grad_out[py, px, ch]
                        grad_alpha += grad_ch * (before * value - behind / keep)
                        g_values[ch] += grad_ch * weight
                    if raw <= MAX_ALPHA32:  # the clamp passes no gradient above its bound
                        grad_power = grad_alpha * alpha
                        g_mx += grad_power * (a_k * dx + b_k * dy)
                        g_my += grad_power * (c_k * dy + b_k * dx)
                        g_a -= HALF * dx * dx * grad_power
                        g_b -= dx * dy * grad_power
                        g_c -= HALF * dy * dy * grad_power
                        g_op += grad_alpha * falloff
                    trans[j] = before * keep
                slot_grads[slot, 0], slot_grads[slot, 1] = g_mx, g_my
                slot_grads[slot, 2], slot_grads[slot, 3], slot_grads[slot, 4] = g_a, g_b, g_c
                slot_grads[slot, 5] = g_op
                for ch in range(channels):
                    slot_grads[slot, 6 + ch] = g_values[ch]
