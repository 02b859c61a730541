"""Differentiable compositing on the CPU with numba: the training path of the rasterizer.

The rule and the inputs are those of :func:`csgs_codec.render.composite_torch.composite`
(the reference, which the tests compare against, images and gradients): Gaussians are
binned into screen tiles, each pixel walks its tile's list front to back in float32, and the
backward pass replays every pixel's walk to form the gradients of the means, conics,
opacities and values (:mod:`csgs_codec.render.numba_kernels`). Tiles run in parallel; the
per-Gaussian sums are taken in a fixed order, so gradients are the same on every run.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from csgs_codec.errors import InputError
from csgs_codec.render.numba_loader import numba_available, rasterizer_kernels
from csgs_codec.render.tiles import tile_ranges

#: Tile side in pixels (speed only: the result does not depend on it).
TRAIN_TILE_SIZE = 16


def numba_compositing_usable(*tensors: torch.Tensor) -> bool:
    """True when numba imports and every tensor is float32 (or integer) on the CPU."""
    return numba_available() and all(
        t.device.type == "cpu" and (not t.is_floating_point() or t.dtype == torch.float32)
        for t in tensors)


def _kernels():
    return rasterizer_kernels("numba compositing")


def _array(t: torch.Tensor) -> np.ndarray:
    return np.ascontiguousarray(t.detach().numpy())


class _TileComposite(torch.autograd.Function):
    """Autograd wrapper of the numba forward and backward kernels (float32, CPU)."""

    @staticmethod
    def forward(ctx, means2d, conics, opacities, values, order, extents, width, height):
        kernels = _kernels()
        tiles_x = math.ceil(width / TRAIN_TILE_SIZE)
        tiles_y = math.ceil(height / TRAIN_TILE_SIZE)
        rects = tile_ranges(means2d.detach(), extents.detach(), width, height,
                            TRAIN_TILE_SIZE).numpy()
        arrays = (_array(means2d), _array(conics), _array(opacities), _array(values))
        offsets, ids = kernels.bin_tiles(rects, _array(order).astype(np.int64),
                                         tiles_x * tiles_y, tiles_x, TRAIN_TILE_SIZE, width,
                                         height, *arrays[:3])
        out = np.zeros((height, width, values.shape[1]), np.float32)
        transmittance = np.ones((height, width), np.float32)
        walked = np.zeros((height, width), np.int32)
        kernels.composite_tiles(offsets, ids, *arrays, width, height, TRAIN_TILE_SIZE,
                                tiles_x, out, transmittance, walked)
        ctx.saved = (offsets, ids, arrays, out, transmittance, walked, width, height, tiles_x)
        ctx.device = means2d.device
        return (torch.as_tensor(out, device=means2d.device),
                torch.as_tensor(transmittance, device=means2d.device))

    @staticmethod
    def backward(ctx, grad_out, grad_transmittance):
        kernels = _kernels()
        offsets, ids, arrays, out, transmittance, walked, width, height, tiles_x = ctx.saved
        n, channels = arrays[3].shape
        slot_grads = np.zeros((ids.shape[0], 6 + channels), np.float32)
        grad_out = (np.zeros_like(out) if grad_out is None
                    else np.ascontiguousarray(grad_out.numpy(), dtype=np.float32))
        grad_t = (np.zeros_like(transmittance) if grad_transmittance is None
                  else np.ascontiguousarray(grad_transmittance.numpy(), dtype=np.float32))
        kernels.composite_tiles_backward(offsets, ids, *arrays, width, height,
                                         TRAIN_TILE_SIZE, tiles_x, out, transmittance, walked,
                                         grad_out, grad_t, slot_grads)
        total = torch.as_tensor(kernels.sum_slots(ids, slot_grads, n).astype(np.float32),
                                device=ctx.device)
        return (total[:, 0:2], total[:, 2:5], total[:, 5], total[:, 6:], None, None, None,
                None)


def composite_numba(order: torch.Tensor, means2d: torch.Tensor, conics: torch.Tensor,
                    opacities: torch.Tensor, extents: torch.Tensor, values: torch.Tensor,
                    width: int, height: int) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`csgs_codec.render.composite_torch.composite`, computed by the numba kernels.

    Args:
        order: [M] int64 Gaussians to draw, near to far.
        means2d: [N, 2] pixels; conics: [N, 3]; opacities: [N]; extents: [N, 2] pixels.
        values: [N, C] per-Gaussian quantities to accumulate.
        width, height: image size in pixels.

    Returns:
        (accumulated [H, W, C], transmittance [H, W]), float32 on the CPU, differentiable
        with respect to means2d, conics, opacities and values.

    Raises:
        InputError: a tensor that is not float32 on the CPU.
        UnsupportedError: numba is not installed.
    """
    for name, t in (("means2d", means2d), ("conics", conics), ("opacities", opacities),
                    ("values", values)):
        if t.device.type != "cpu" or t.dtype != torch.float32:
            raise InputError(f"numba compositing takes float32 CPU tensors, got {t.dtype} on "
                             f"{t.device}", property=name)
    if order.numel() == 0:  # nothing drawn: constant maps, as the reference gives
        return (torch.zeros(height, width, values.shape[1], device=values.device),
                torch.ones(height, width, device=values.device))
    return _TileComposite.apply(means2d, conics, opacities, values, order, extents, width,
                                height)
