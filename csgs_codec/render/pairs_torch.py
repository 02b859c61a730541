"""Which (Gaussian, pixel) pairs the torch compositor evaluates (torch, no gradients).

Every Gaussian covers the pixels of its footprint ellipse (outside it alpha is below 1/255
by construction). The image is cut into bands of rows and each band's Gaussians into depth
chunks, front to back, so the compositor can drop pixels that are already opaque before
enumerating the pairs of the Gaussians behind them.
"""

from __future__ import annotations

import torch

from csgs_codec.render.projection import ALPHA_THRESHOLD


def pixel_boxes(means2d: torch.Tensor, extents: torch.Tensor, width: int,
                 height: int) -> torch.Tensor:
    """[N, 4] int64 pixel ranges (u0, u1, v0, v1), half-open, clipped to the image.

    Pixel u is in the box when its centre u + 0.5 lies within mean +- extent.
    """
    m = means2d.detach().to(torch.float64)
    e = extents.detach().to(torch.float64)
    lo = torch.ceil(m - e - 0.5)
    hi = torch.floor(m + e - 0.5) + 1
    lo = torch.nan_to_num(lo, nan=0.0, posinf=1e9, neginf=-1e9)
    hi = torch.nan_to_num(hi, nan=0.0, posinf=1e9, neginf=-1e9)
    u0, u1 = lo[:, 0].clamp(0, width), hi[:, 0].clamp(0, width)
    v0, v1 = lo[:, 1].clamp(0, height), hi[:, 1].clamp(0, height)
    u1, v1 = torch.maximum(u0, u1), torch.maximum(v0, v1)
    return torch.stack([u0, u1, v0, v1], dim=-1).to(torch.int64)


def row_bands(boxes: torch.Tensor, height: int, budget: int) -> list[tuple[int, int]]:
    """Split rows 0..height into bands whose pair counts stay under ``budget`` if possible."""
    widths = boxes[:, 1] - boxes[:, 0]
    per_row_delta = torch.zeros(height + 1, dtype=torch.int64, device=boxes.device)
    per_row_delta.index_add_(0, boxes[:, 2], widths)
    per_row_delta.index_add_(0, boxes[:, 3], -widths)
    per_row = torch.cumsum(per_row_delta, 0)[:height].tolist()
    bands, start, load = [], 0, 0
    for row, pairs in enumerate(per_row):
        if load and load + pairs > budget:
            bands.append((start, row))
            start, load = row, 0
        load += pairs
    bands.append((start, height))
    return bands


def pack_columns(means2d: torch.Tensor, conics: torch.Tensor,
          opacities: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Six contiguous [N] tensors (mean x, mean y, conic a, b, c, opacity).

    Gathering 1-D tensors per pair is several times faster in torch than gathering rows.
    (Differentiable: the columns are views of the inputs made contiguous.)
    """
    return (means2d[:, 0].contiguous(), means2d[:, 1].contiguous(), conics[:, 0].contiguous(),
            conics[:, 1].contiguous(), conics[:, 2].contiguous(), opacities.contiguous())


def gather(columns: tuple[torch.Tensor, ...], index: torch.Tensor) -> list[torch.Tensor]:
    """Each [N] column gathered at ``index`` [P] -> list of [P] tensors."""
    return [col.index_select(0, index) for col in columns]


def pixel_centres(row0: int, rows: int, width: int, dtype: torch.dtype, *,
                  device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    """Centre x [rows * W] and y [rows * W] of every pixel of a band, row-major, on
    ``device``."""
    ys, xs = torch.meshgrid(torch.arange(row0, row0 + rows, dtype=dtype, device=device) + 0.5,
                            torch.arange(width, dtype=dtype, device=device) + 0.5,
                            indexing="ij")
    return xs.flatten(), ys.flatten()


def band_pairs(order: torch.Tensor, boxes: torch.Tensor, packed: tuple[torch.Tensor, ...],
               row0: int, row1: int, width: int,
               done: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Candidate pairs of the Gaussians ``order`` (near to far) in rows row0..row1, sorted by
    (pixel, depth), leaving out pixels already ``done`` ([rows * W] bool) when given.

    Each Gaussian's box is cut row by row to the pixel span of the ellipse where its alpha can
    reach 1/255 (widened by half a pixel; the exact per-pair test is made when compositing).

    Returns (gaussian [P], pixel [P] row-major index inside the band), both int64.
    """
    b = boxes[order]
    hit = (b[:, 2] < row1) & (b[:, 3] > row0) & (b[:, 1] > b[:, 0])
    sub, b = order[hit], b[hit]
    v0 = b[:, 2].clamp(min=row0)
    heights = b[:, 3].clamp(max=row1) - v0
    n_rows = int(heights.sum())
    device = order.device
    empty = torch.zeros(0, dtype=torch.int64, device=device)
    if n_rows == 0:
        return empty, empty
    owner = torch.repeat_interleave(torch.arange(sub.numel(), device=device), heights)
    row = (v0[owner] + torch.arange(n_rows, device=device)
           - (torch.cumsum(heights, 0) - heights)[owner])
    g = sub[owner]
    mx, my, a, bb, c, op = (col.to(torch.float64) for col in gather(packed, g))
    k = 2.0 * torch.log(torch.clamp(op / ALPHA_THRESHOLD, min=1.0))
    dy = row.to(torch.float64) + 0.5 - my
    # a dx^2 + 2 b dx dy + c dy^2 <= k, solved for dx on this row; u + 0.5 = mean x + dx.
    disc = dy * dy * (bb * bb - a * c) + a * k
    half = torch.sqrt(torch.clamp(disc, min=0.0)) / a
    centre = mx - bb * dy / a - 0.5
    lo = torch.maximum(torch.ceil(centre - half - 0.5), b[owner, 0].to(torch.float64))
    hi = torch.minimum(torch.floor(centre + half + 0.5) + 1, b[owner, 1].to(torch.float64))
    lo = lo.to(torch.int64)
    widths = torch.where(disc >= 0, torch.clamp(hi.to(torch.int64) - lo, min=0),
                         torch.zeros_like(lo))
    total = int(widths.sum())
    if total == 0:
        return empty, empty
    owner = torch.repeat_interleave(torch.arange(n_rows, device=device), widths)
    start = (row - row0) * width + lo - (torch.cumsum(widths, 0) - widths)
    pixel = start[owner] + torch.arange(total, device=device)
    g = g.index_select(0, owner)
    if done is not None:
        open_pair = ~done.index_select(0, pixel)
        pixel, g = pixel[open_pair], g[open_pair]
    # Pairs were generated near to far, so a stable sort by pixel gives (pixel, depth) order.
    pixel, perm = torch.sort(pixel.to(torch.int32), stable=True)
    return g.index_select(0, perm), pixel.to(torch.int64)


def depth_chunks(order: torch.Tensor, boxes: torch.Tensor, row0: int, row1: int,
                 budget: int) -> list[torch.Tensor]:
    """The Gaussians of ``order`` touching rows row0..row1, split near to far into chunks of
    at most ``budget`` box pixels (a chunk holds at least one Gaussian)."""
    b = boxes[order]
    hit = (b[:, 2] < row1) & (b[:, 3] > row0) & (b[:, 1] > b[:, 0])
    sub, b = order[hit], b[hit]
    area = (b[:, 1] - b[:, 0]) * (b[:, 3].clamp(max=row1) - b[:, 2].clamp(min=row0))
    chunk_of = (torch.cumsum(area, 0) - area) // budget
    if sub.numel() == 0:
        return []
    sizes = torch.unique_consecutive(chunk_of, return_counts=True)[1].tolist()
    return list(torch.split(sub, sizes))


def still_open(gaussians: torch.Tensor, boxes: torch.Tensor, done: torch.Tensor, row0: int,
               width: int) -> torch.Tensor:
    """Mask of the ``gaussians`` whose box (in this band) holds a pixel not yet opaque.

    ``done`` is the band's [rows * W] bool map of pixels whose compositing has stopped; a
    summed-area table answers each box with four lookups.
    """
    rows = done.numel() // width
    table = torch.zeros(rows + 1, width + 1, dtype=torch.int64, device=done.device)
    table[1:, 1:] = torch.cumsum(torch.cumsum((~done).reshape(rows, width).to(torch.int64),
                                              0), 1)
    b = boxes[gaussians]
    u0, u1 = b[:, 0], b[:, 1]
    v0, v1 = (b[:, 2] - row0).clamp(0, rows), (b[:, 3] - row0).clamp(0, rows)
    flat = table.flatten()
    stride = width + 1
    count = (flat[v1 * stride + u1] - flat[v0 * stride + u1] - flat[v1 * stride + u0]
             + flat[v0 * stride + u0])
    return count > 0
