"""The per-pixel walk written plainly, as the numba compositing kernels ran before they went
a row at a time: every pixel of a tile tries every Gaussian of the tile's list, near to far.
The tests hold :mod:`csgs_codec.render.numba_composite` to it bit for bit."""

from __future__ import annotations

import numba
import numpy as np

from csgs_codec.render.numba_pixel import HALF, MAX_ALPHA32, ONE, T_STOP, alpha_at, pack_tile


@numba.njit(cache=False)
def plain_composite(offsets, ids, means2d, conics, opacities, values, width, height,
                    tile_size, tiles_x, out, transmittance, walked):
    """Forward: ``out`` (zeroed), ``transmittance`` (ones) and ``walked`` as the kernel
    fills them."""
    channels = values.shape[1]
    for t in range(offsets.shape[0] - 1):
        start = offsets[t]
        count = offsets[t + 1] - start
        if count == 0:
            continue
        packed = pack_tile(ids, start, count, means2d, conics, opacities)
        x0 = (t % tiles_x) * tile_size
        y0 = (t // tiles_x) * tile_size
        for py in range(y0, min(y0 + tile_size, height)):
            pyc = np.float32(py) + HALF
            for px in range(x0, min(x0 + tile_size, width)):
                pxc = np.float32(px) + HALF
                trans = ONE
                stop = count
                for k in range(count):
                    alpha, _, _, _ = alpha_at(packed, k, pxc, pyc)
                    if alpha == 0:
                        continue
                    after = trans * (ONE - alpha)
                    if after < T_STOP:
                        stop = k
                        break
                    weight = alpha * trans
                    g = ids[start + k]
                    for ch in range(channels):
                        out[py, px, ch] += weight * values[g, ch]
                    trans = after
                transmittance[py, px] = trans
                walked[py, px] = stop


@numba.njit(cache=False)
def plain_backward(offsets, ids, means2d, conics, opacities, values, width, height, tile_size,
                   tiles_x, out, transmittance, walked, grad_out, grad_transmittance,
                   slot_grads):
    """Backward: ``slot_grads`` [I, 6 + C] (zeroed) as the kernel fills it."""
    channels = values.shape[1]
    for t in range(offsets.shape[0] - 1):
        start = offsets[t]
        count = offsets[t + 1] - start
        if count == 0:
            continue
        packed = pack_tile(ids, start, count, means2d, conics, opacities)
        running = np.empty(channels, np.float32)
        x0 = (t % tiles_x) * tile_size
        y0 = (t // tiles_x) * tile_size
        for py in range(y0, min(y0 + tile_size, height)):
            pyc = np.float32(py) + HALF
            for px in range(x0, min(x0 + tile_size, width)):
                stop = walked[py, px]
                if stop == 0:
                    continue
                pxc = np.float32(px) + HALF
                final = transmittance[py, px]
                grad_t = grad_transmittance[py, px]
                for ch in range(channels):
                    running[ch] = np.float32(0.0)
                trans = ONE
                for k in range(stop):
                    alpha, falloff, dx, dy = alpha_at(packed, k, pxc, pyc)
                    if alpha == 0:
                        continue
                    raw = packed[k, 5] * falloff
                    keep = ONE - alpha
                    weight = alpha * trans
                    g = ids[start + k]
                    slot = start + k
                    grad_alpha = -grad_t * final / keep
                    for ch in range(channels):
                        value = values[g, ch]
                        running[ch] += weight * value
                        behind = out[py, px, ch] - running[ch]
                        grad_c = grad_out[py, px, ch]
                        grad_alpha += grad_c * (trans * value - behind / keep)
                        slot_grads[slot, 6 + ch] += grad_c * weight
                    if raw <= MAX_ALPHA32:
                        grad_power = grad_alpha * alpha
                        slot_grads[slot, 0] += grad_power * (packed[k, 2] * dx
                                                             + packed[k, 3] * dy)
                        slot_grads[slot, 1] += grad_power * (packed[k, 4] * dy
                                                             + packed[k, 3] * dx)
                        slot_grads[slot, 2] -= HALF * dx * dx * grad_power
                        slot_grads[slot, 3] -= dx * dy * grad_power
                        slot_grads[slot, 4] -= HALF * dy * dy * grad_power
                        slot_grads[slot, 5] += grad_alpha * falloff
                    trans = trans * keep
