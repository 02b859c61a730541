"""Objects from over-segments: the built-in segmenter's masks made into instance masks by the
scene's own 3D structure.

The built-in segmenter (:mod:`.segmentation`) splits textured objects into many segments and
merges objects of similar colour, differently in every view, so training on its masks gives
dozens of instances per object. The groups (Gaussians, or anchors) behind the views say which
segments belong together:

1. **Connectivity.** Each group is linked to its :data:`NEIGHBOURS` nearest groups
   (:func:`~csgs_codec.train.instances.approximate_neighbours`) that lie within :data:`GAP`
   times the smaller of the two groups' spacings (a group's spacing: the distance to its
   :data:`NEIGHBOURS`-th nearest); the connected components of those links are the pieces.
   Objects that stand apart share no link, and a floater far from everything is a piece of
   its own, whatever its colour.
2. **Agreement across views.** Pixels whose accumulated opacity is at least
   :data:`MIN_ALPHA` are the views' object pixels. In each view, a piece's rendered weight
   over those pixels spreads over the view's segments; two pieces agree in the view by the
   Bhattacharyya overlap of their spreads (1 when both fall in the same segments in the same
   proportions, 0 when they share none). Pieces whose overlap, averaged over the views that
   see both (each with at least :data:`MIN_VIEW_WEIGHT` of weight), reaches :data:`AGREE` are
   one object: a piece the spacing rule cut off (a sparse stem, a thin handle) rejoins its
   object where the segments show them together, while two objects the segmenter merged in a
   few views stay apart because the other views split them. Only the
   :data:`MAX_PIECES` pieces of most rendered weight take part (the rest are specks).
3. **Masks.** In each view, a pixel takes the object that carries the most of its rendered
   weight; pixels under :data:`MIN_ALPHA` take :data:`BACKGROUND_ID`. Objects are numbered
   from 1 by decreasing rendered weight over all views (ties: lowest group first).

Measured (benchmarks/segment_auto.py, 24 views of 320x240, 3D click mIoU): real objects
placed apart, 2 and 6 of them, 0.35 / 0.51 on the segmenter's masks as instances, 0.98 / 1.00
with this step (the exact masks: 1.00); mary_rose trained without instance masks, 2D click IoU
against its foreground masks 0.16 -> 0.96. Objects that touch stay one piece: fruit_drops'
letters on their card 0.51 -> 0.12.

The masks are consistent across views (one id per object everywhere), so the contrastive
stage and the lifting that follow treat them as user instance masks. Everything is
deterministic: stable sorts, minimum-label components, no random numbers.
"""

from __future__ import annotations

import numpy as np
import torch

from csgs_codec.errors import InputError
from csgs_codec.train.instances import approximate_neighbours

#: Nearest groups each group may link to, and whose farthest sets its spacing.
NEIGHBOURS = 8
#: A link is kept up to this many times the smaller spacing of its two groups.
GAP = 3.0
#: Pixels with less accumulated opacity are background in the masks and the agreement.
MIN_ALPHA = 0.5
#: Mean cross-view overlap of their segment spreads at which two pieces are one object.
AGREE = 0.5
#: Rendered weight a piece needs in a view (summed over its object pixels) for the view to
#: count in its agreement.
MIN_VIEW_WEIGHT = 4.0
#: Most pieces that take part in the agreement (by rendered weight).
MAX_PIECES = 1024
#: Mask id of background pixels.
BACKGROUND_ID = 0


def object_masks(contributions: list[torch.Tensor], segments: list[np.ndarray],
                 positions: np.ndarray) -> list[np.ndarray]:
    """Instance masks, consistent across views, from per-view over-segments (module notes).

    Args:
        contributions: per view, the sparse (H_v * W_v, G) contribution matrix
            (:func:`~csgs_codec.train.semantic_stage.contribution_matrix`).
        segments: per view, (H_v, W_v) integer segment ids (any integers).
        positions: (G, 3) positions of the groups, world units.

    Returns:
        Per view, an (H_v, W_v) int32 mask: object ids from 1, :data:`BACKGROUND_ID` where
        the view shows no object.

    Raises:
        InputError: lists of different lengths, or a matrix that does not match its
            segments or the positions.
    """
    positions = np.asarray(positions, np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3 or not np.isfinite(positions).all():
        raise InputError(f"positions must be finite (G, 3), got {positions.shape}",
                         property="positions")
    if len(contributions) != len(segments):
        raise InputError(f"{len(contributions)} contribution matrices for {len(segments)} "
                         "segment images", property="segments")
    groups = len(positions)
    views = []
    for v, (matrix, segment) in enumerate(zip(contributions, segments)):
        segment = np.asarray(segment)
        if segment.ndim != 2 or tuple(matrix.shape) != (segment.size, groups):
            raise InputError(f"view {v}: contributions {tuple(matrix.shape)} do not match "
                             f"segments {segment.shape} and {groups} groups", index=v,
                             property="contributions")
        views.append(_view_pairs(matrix, segment))
    pieces = connected_pieces(positions)
    objects = _numbered(_merge_agreeing(pieces, views, groups), views)
    return [_render_mask(view, objects, segment.shape)
            for view, segment in zip(views, segments)]


def _numbered(objects: np.ndarray, views: list[_ViewPairs]) -> np.ndarray:
    """(G,) int64 objects renumbered 0.. by decreasing rendered weight over all views (ties:
    the object of the lowest group first)."""
    _, dense = np.unique(objects, return_inverse=True)
    count = int(dense.max()) + 1 if dense.size else 0
    total = np.zeros(count)
    for view in views:
        total += np.bincount(dense[view.group], weights=view.weight, minlength=count)
    rank = np.empty(count, np.int64)
    rank[np.lexsort((np.arange(count), -total))] = np.arange(count)
    return rank[dense]


def connected_pieces(positions: np.ndarray, *, neighbours: int = NEIGHBOURS,
                     gap: float = GAP) -> np.ndarray:
    """(G,) int64 piece of each group: components of the neighbour links within ``gap`` times
    the smaller spacing (module notes, step 1), numbered by their lowest group."""
    count = len(positions)
    if count < 2:
        return np.zeros(count, np.int64)
    k = min(neighbours + 1, count)
    near = approximate_neighbours(positions, k)[:, 1:]
    distance = np.sqrt(np.sum((positions[near] - positions[:, None]) ** 2, axis=2))
    spacing = distance[:, -1]
    limit = gap * np.minimum(spacing[:, None], spacing[near])
    first = np.repeat(np.arange(count), k - 1)
    keep = (distance <= limit).ravel()
    return components(count, first[keep], near.ravel()[keep])


def components(count: int, first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """(count,) int64 connected component of each node given the edges ``first[i]`` -
    ``second[i]``, each component named by its lowest node (min-label hooking and pointer
    jumping; deterministic)."""
    label = np.arange(count, dtype=np.int64)
    first = np.asarray(first, np.int64)
    second = np.asarray(second, np.int64)
    while True:
        a, b = label[first], label[second]
        differ = a != b
        if not differ.any():
            return label
        a, b = a[differ], b[differ]
        low = np.minimum(a, b)
        np.minimum.at(label, a, low)
        np.minimum.at(label, b, low)
        while True:
            jumped = label[label]
            if np.array_equal(jumped, label):
                break
            label = jumped


class _ViewPairs:
    """One view's contributing (pixel, group, weight) triplets (int32, int32, float32: the
    views' triplets are all held at once), its pixels' accumulated opacity (float64) and
    segment ids."""

    def __init__(self, pixel: np.ndarray, group: np.ndarray, weight: np.ndarray,
                 alpha: np.ndarray, segment: np.ndarray):
        self.pixel, self.group, self.weight = pixel, group, weight
        self.alpha, self.segment = alpha, segment


def _view_pairs(matrix: torch.Tensor, segment: np.ndarray) -> _ViewPairs:
    coo = matrix.coalesce()
    pixel, group = (index.cpu().numpy().astype(np.int32) for index in coo.indices())
    weight = coo.values().cpu().numpy().astype(np.float32)
    alpha = np.bincount(pixel, weights=weight, minlength=segment.size)
    _, flat = np.unique(segment.ravel(), return_inverse=True)
    return _ViewPairs(pixel, group, weight, alpha, flat.astype(np.int32))


def _merge_agreeing(pieces: np.ndarray, views: list[_ViewPairs], groups: int) -> np.ndarray:
    """(G,) int64 object of each group: pieces merged where their segment spreads agree
    across views (module notes, step 2), numbered by the lowest group."""
    _, piece = np.unique(pieces, return_inverse=True)
    count = int(piece.max()) + 1 if groups else 0
    total = np.zeros(count)
    for view in views:
        total += np.bincount(piece[view.group], weights=view.weight, minlength=count)
    chosen = np.lexsort((np.arange(count), -total))[:MAX_PIECES]
    chosen = chosen[total[chosen] > 0]
    if len(chosen) < 2:
        return pieces
    slot = np.full(count, -1, np.int64)
    slot[chosen] = np.arange(len(chosen))
    overlap = np.zeros((len(chosen), len(chosen)))
    seen_together = np.zeros((len(chosen), len(chosen)))
    for view in views:
        rows = slot[piece[view.group]]
        kept = (rows >= 0) & (view.alpha[view.pixel] >= MIN_ALPHA)
        segments = int(view.segment.max()) + 1
        spread = np.zeros((len(chosen), segments))
        np.add.at(spread, (rows[kept], view.segment[view.pixel[kept]]), view.weight[kept])
        weight = spread.sum(axis=1)
        seen = weight >= MIN_VIEW_WEIGHT
        share = np.sqrt(spread / np.where(weight > 0, weight, 1.0)[:, None])
        share[~seen] = 0.0
        overlap += share @ share.T
        seen_together += np.outer(seen, seen)
    agree = overlap >= AGREE * np.maximum(seen_together, 1.0)
    agree &= seen_together > 0
    first, second = np.nonzero(np.triu(agree, 1))
    merged = components(len(chosen), first, second)
    names = np.arange(count, dtype=np.int64)
    names[chosen] = chosen[merged]
    # Each object is named by its lowest group.
    objects = names[piece]
    lowest = np.full(count, groups, np.int64)
    np.minimum.at(lowest, objects, np.arange(groups))
    return lowest[objects]


def _render_mask(view: _ViewPairs, objects: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) int32 mask of one view: each object pixel's heaviest object (module notes)."""
    mask = np.full(shape[0] * shape[1], BACKGROUND_ID, np.int32)
    if view.pixel.size == 0:
        return mask.reshape(shape)
    span = int(objects.max()) + 1
    key = view.pixel.astype(np.int64) * span + objects[view.group]
    unique, inverse = np.unique(key, return_inverse=True)
    summed = np.bincount(inverse, weights=view.weight)
    pixel, name = unique // span, unique % span
    order = np.lexsort((name, -summed, pixel))
    first = np.ones(order.size, bool)
    first[1:] = pixel[order][1:] != pixel[order][:-1]
    best_pixel, best_name = pixel[order][first], name[order][first]
    shown = view.alpha[best_pixel] >= MIN_ALPHA
    mask[best_pixel[shown]] = best_name[shown] + 1
    return mask.reshape(shape)
