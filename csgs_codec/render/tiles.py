"""Depth order and screen-tile ranges of projected Gaussians (torch, no gradients)."""

from __future__ import annotations

import math

import torch

from csgs_codec.render.projection import ProjectedGaussians


def depth_order(depths: torch.Tensor, visible: torch.Tensor) -> torch.Tensor:
    """Indices of the visible Gaussians sorted near to far (stable: ties keep input order).

    Args:
        depths: [N] camera-space z.
        visible: [N] bool.

    Returns:
        [M] int64 indices into the N Gaussians, M = visible.sum().
    """
    ids = torch.nonzero(visible, as_tuple=False).flatten()
    order = torch.sort(depths.detach()[ids], stable=True).indices
    return ids[order]


def tile_ranges(means2d: torch.Tensor, extents: torch.Tensor, width: int, height: int,
                tile_size: int) -> torch.Tensor:
    """Range of tiles each footprint box (mean +- extent, pixels) touches.

    Returns:
        [N, 4] int64 (tx0, tx1, ty0, ty1), half-open tile ranges clipped to the image, on the
        device of ``means2d``.
    """
    tiles_x = math.ceil(width / tile_size)
    tiles_y = math.ceil(height / tile_size)
    with torch.no_grad():
        lo = torch.floor((means2d - extents) / tile_size)
        hi = torch.floor((means2d + extents) / tile_size) + 1
        lo = torch.nan_to_num(lo, nan=0.0, posinf=1e9, neginf=-1e9).to(torch.float64)
        hi = torch.nan_to_num(hi, nan=0.0, posinf=1e9, neginf=-1e9).to(torch.float64)
        tx0 = lo[:, 0].clamp(0, tiles_x).to(torch.int64)
        tx1 = torch.maximum(hi[:, 0].clamp(0, tiles_x).to(torch.int64), tx0)
        ty0 = lo[:, 1].clamp(0, tiles_y).to(torch.int64)
        ty1 = torch.maximum(hi[:, 1].clamp(0, tiles_y).to(torch.int64), ty0)
    return torch.stack([tx0, tx1, ty0, ty1], dim=-1)


def tile_rectangles(projected: ProjectedGaussians, width: int, height: int,
                    tile_size: int) -> torch.Tensor:
    """Range of tiles each Gaussian's footprint box touches.

    Args:
        projected: output of :func:`project_gaussians`.
        width, height: image size in pixels.
        tile_size: tile side in pixels.

    Returns:
        [N, 4] int64 (tx0, tx1, ty0, ty1), half-open tile ranges clipped to the image; empty
        (tx0 == tx1) for culled Gaussians.
    """
    rects = tile_ranges(projected.means2d, projected.extents, width, height, tile_size)
    hidden = ~projected.visible
    rects[hidden, 1] = rects[hidden, 0]
    rects[hidden, 3] = rects[hidden, 2]
    return rects
