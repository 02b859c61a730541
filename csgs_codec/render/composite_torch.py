"""Differentiable front-to-back alpha compositing over (Gaussian, pixel) pairs (torch).

Rule for one pixel p and its Gaussians i = 1, 2, ... near to far (T starts at 1):

    alpha_i = min(0.99, opacity_i * exp(-0.5 d^T S_i^-1 d)),  d = p - mean_i
    skip i when alpha_i < 1/255
    stop (and skip i) when T * (1 - alpha_i) < 1e-4
    value += values_i * alpha_i * T;  T *= 1 - alpha_i

Vectorised form: pairs (from :mod:`csgs_codec.render.pairs_torch`) are put in (pixel, depth)
order and a segmented cumulative sum of log(1 - alpha), started from the pixel's
transmittance so far, gives each pair's transmittance. A selection pass without gradients
walks each band's Gaussians in depth chunks, front to back, skipping Gaussians and pixels
that are already opaque, and keeps only the pairs that contribute; the compositing pass
(differentiable when needed) then evaluates just those. Bands of rows and depth chunks keep
memory bounded.
"""

from __future__ import annotations

import torch
from torch.utils.checkpoint import checkpoint

from csgs_codec.render.pairs_torch import (
    band_pairs,
    depth_chunks,
    gather,
    pack_columns,
    pixel_boxes,
    pixel_centres,
    row_bands,
    still_open,
)
from csgs_codec.render.projection import ALPHA_THRESHOLD

#: Compositing stops when transmittance would fall below this.
TRANSMITTANCE_STOP = 1e-4
#: Largest alpha a single Gaussian can have.
MAX_ALPHA = 0.99
#: Most footprint-box pixels per band of rows (unless a single row holds more).
PAIR_BUDGET = 1 << 22
#: Most footprint-box pixels per depth chunk inside a band.
CHUNK_BUDGET = 1 << 20
#: When training, the contributing pairs whose intermediates are kept for the backward pass;
#: bands beyond this are recomputed in the backward pass instead (gradient checkpointing).
STORED_PAIR_BUDGET = 1 << 23


def _pair_terms(g: torch.Tensor, pixel: torch.Tensor, packed: tuple[torch.Tensor, ...],
                centres: tuple[torch.Tensor, torch.Tensor], log_t: torch.Tensor,
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Compositing terms of pairs sorted by (pixel, depth).

    Args:
        g: [P] Gaussian of each pair; pixel: [P] its pixel in the band.
        packed: columns from ``pack_columns``; centres: from ``pixel_centres``.
        log_t: [n_pix] log transmittance of each pixel before these pairs.

    Returns:
        (weight alpha * T_before [P], 0 unless the pair contributes; log(1 - alpha) [P], 0
        unless it contributes; contributes [P] bool; stops [P] bool, the pairs that would
        take T below the stop level).
    """
    mx, my, a, b, c, op = gather(packed, g)
    dx = centres[0].index_select(0, pixel) - mx
    dy = centres[1].index_select(0, pixel) - my
    power = -0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy
    alpha = torch.clamp(op * torch.exp(power), max=MAX_ALPHA)
    alpha = torch.where(alpha >= ALPHA_THRESHOLD, alpha, torch.zeros_like(alpha))
    log_keep = torch.log1p(-alpha)
    # float64 running sums: the band-wide sum is large, per-pixel differences are small.
    log_keep64 = log_keep.to(torch.float64)
    running = torch.cumsum(log_keep64, 0)
    counts = torch.bincount(pixel, minlength=centres[0].shape[0])
    seg_start = (torch.cumsum(counts, 0) - counts).index_select(0, pixel)
    before = running - log_keep64
    before = (before - before.index_select(0, seg_start)).to(alpha.dtype)
    before = before + log_t.index_select(0, pixel)
    with torch.no_grad():
        after_ok = torch.exp(before + log_keep) >= TRANSMITTANCE_STOP
        contributes = after_ok & (alpha > 0)
        stops = ~after_ok
    zero = torch.zeros_like(alpha)
    weights = torch.where(contributes, alpha * torch.exp(before), zero)
    return weights, torch.where(contributes, log_keep, zero), contributes, stops


def _select_band(order: torch.Tensor, boxes: torch.Tensor, packed: tuple[torch.Tensor, ...],
                 centres: tuple[torch.Tensor, torch.Tensor], row0: int, row1: int,
                 width: int) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """The contributing pairs of one band, as (gaussian [P], pixel [P]) per depth chunk."""
    n_pix = centres[0].shape[0]
    dtype, device = centres[0].dtype, centres[0].device
    log_t = torch.zeros(n_pix, dtype=dtype, device=device)
    done = torch.zeros(n_pix, dtype=torch.bool, device=device)
    selected = []
    for chunk in depth_chunks(order, boxes, row0, row1, CHUNK_BUDGET):
        if selected:
            chunk = chunk[still_open(chunk, boxes, done, row0, width)]
        g, pixel = band_pairs(chunk, boxes, packed, row0, row1, width, done)
        if g.numel() == 0:
            continue
        _, log_keep, contributes, stops = _pair_terms(g, pixel, packed, centres, log_t)
        log_t = log_t.index_add(0, pixel, log_keep)
        done[pixel[stops]] = True
        selected.append((g[contributes], pixel[contributes]))
    return selected


def _composite_band(pairs: list[tuple[torch.Tensor, torch.Tensor]],
                    packed: tuple[torch.Tensor, ...], centres: tuple[torch.Tensor, torch.Tensor],
                    values_t: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite one band's selected pairs, chunk after chunk.

    ``values_t`` is [C, N]; returns (accumulated [C, n_pix], transmittance [n_pix]).
    """
    n_pix = centres[0].shape[0]
    acc = torch.zeros(values_t.shape[0], n_pix, dtype=values_t.dtype, device=values_t.device)
    log_t = torch.zeros(n_pix, dtype=values_t.dtype, device=values_t.device)
    for g, pixel in pairs:
        weights, log_keep, _, _ = _pair_terms(g, pixel, packed, centres, log_t)
        per_pair = torch.stack(gather(tuple(values_t.unbind(0)), g)) * weights
        acc = acc.index_add(1, pixel, per_pair)
        log_t = log_t.index_add(0, pixel, log_keep)
    return acc, torch.exp(log_t)


def composite(order: torch.Tensor, means2d: torch.Tensor, conics: torch.Tensor,
              opacities: torch.Tensor, extents: torch.Tensor, values: torch.Tensor,
              width: int, height: int, *, pair_budget: int = PAIR_BUDGET,
              checkpointed: bool | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite Gaussians into an image, differentiably.

    Args:
        order: [M] int64 indices of the Gaussians to draw, near to far.
        means2d: [N, 2] pixel coordinates; conics: [N, 3]; opacities: [N] in (0, 1).
        extents: [N, 2] footprint half sizes in pixels (alpha < 1/255 outside).
        values: [N, C] per-Gaussian quantities to accumulate (color, depth, features).
        width, height: image size in pixels.
        pair_budget: most footprint-box pixels per band of rows.
        checkpointed: True recomputes every band in the backward pass instead of storing its
            intermediates, False stores all; None (default) stores bands until
            :data:`STORED_PAIR_BUDGET` contributing pairs are held, then recomputes the rest,
            so training memory stays bounded and small views pay nothing.

    Returns:
        (accumulated [H, W, C] sum of weight * value, transmittance [H, W] left after the last
        contributing Gaussian; 1 - transmittance is the accumulated alpha).
    """
    dtype = values.dtype
    needs_grad = torch.is_grad_enabled() and any(
        t.requires_grad for t in (means2d, conics, opacities, values))
    packed = pack_columns(means2d, conics, opacities.to(dtype))
    values_t = values.T.contiguous()
    boxes = pixel_boxes(means2d, extents, width, height)
    acc_parts, t_parts = [], []
    stored_pairs = 0
    for row0, row1 in row_bands(boxes[order], height, pair_budget):
        centres = pixel_centres(row0, row1 - row0, width, dtype, device=values.device)
        with torch.no_grad():
            pairs = _select_band(order, boxes, tuple(t.detach() for t in packed), centres,
                                 row0, row1, width)
        band_pair_count = sum(g.numel() for g, _ in pairs)
        recompute = checkpointed
        if recompute is None:
            recompute = needs_grad and stored_pairs + band_pair_count > STORED_PAIR_BUDGET
            stored_pairs += 0 if recompute else band_pair_count
        if needs_grad and recompute:
            acc, trans = checkpoint(_composite_band, pairs, packed, centres, values_t,
                                    use_reentrant=False)
        else:
            acc, trans = _composite_band(pairs, packed, centres, values_t)
        acc_parts.append(acc)
        t_parts.append(trans)
    acc = torch.cat(acc_parts, dim=1).T.reshape(height, width, values.shape[1])
    return acc, torch.cat(t_parts).reshape(height, width)


def composite_weights(order: torch.Tensor, means2d: torch.Tensor, conics: torch.Tensor,
                      opacities: torch.Tensor, extents: torch.Tensor, width: int, height: int,
                      *, pair_budget: int = PAIR_BUDGET
                      ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Every contributing (pixel, Gaussian) pair of one view with its compositing weight.

    The weight is alpha_i * T_i(p), so that :func:`composite` of any per-Gaussian values v is
    ``sum over pairs of weight * v[gaussian]`` at each pixel: one pass gives the linear map
    from per-Gaussian features to the rendered feature map (stages 2-3, geometry fixed).

    Args:
        order, means2d, conics, opacities, extents, width, height, pair_budget: as for
            :func:`composite`.

    Returns:
        (pixel [P] int64 row-major index in the H x W image, gaussian [P] int64, weight [P]
        dtype of ``means2d``), on the device of the inputs, without gradients.
    """
    dtype, device = means2d.dtype, means2d.device
    with torch.no_grad():
        packed = pack_columns(means2d, conics, opacities.to(dtype))
        boxes = pixel_boxes(means2d, extents, width, height)
        pixels, gaussians, weights = [], [], []
        for row0, row1 in row_bands(boxes[order], height, pair_budget):
            centres = pixel_centres(row0, row1 - row0, width, dtype, device=device)
            log_t = torch.zeros(centres[0].shape[0], dtype=dtype, device=device)
            for g, pixel in _select_band(order, boxes, packed, centres, row0, row1, width):
                weight, log_keep, _, _ = _pair_terms(g, pixel, packed, centres, log_t)
                log_t = log_t.index_add(0, pixel, log_keep)
                pixels.append(pixel + row0 * width)
                gaussians.append(g)
                weights.append(weight)
    if not pixels:
        empty = torch.zeros(0, dtype=torch.int64, device=device)
        return empty, empty.clone(), torch.zeros(0, dtype=dtype, device=device)
    return torch.cat(pixels), torch.cat(gaussians), torch.cat(weights)
