"""Groups of neighbouring Gaussians to merge: equal-count k-d cells of about ``size`` each.

Within every segment (a tile of the level being built) of n points the points are cut into
g = ceil(n / size) groups: a cell holding g > 1 groups is cut in two across the longest side of
its points' box, at the point count proportional to the groups each half gets (ceil(g / 2)
below the cut), until every cell holds one group. Points are ranked along the axis by
(coordinate, input index), so ties cut the same way on every machine. All segments are cut
side by side, one sort of all points per round (about log2(n / size) rounds).
"""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import InputError

#: Gaussians merged into one, at most (every level holds about 1 / GROUP_SIZE of the one
#: below it).
GROUP_SIZE = 8


def group_ids(positions: np.ndarray, segments: np.ndarray, size: int = GROUP_SIZE
              ) -> np.ndarray:
    """The group of every point: (N,) int64 ids 0..G-1, numbered segment by segment in
    increasing segment order, then in k-d order within the segment.

    Args:
        positions: (N, 3) float world units.
        segments: (N,) int segment of each point (groups never span two segments).
        size: most points a group holds (>= 1).

    Returns:
        (N,) int64 group ids; a segment of n points has ceil(n / size) groups.
    """
    if size < 1:
        raise InputError(f"group size must be >= 1, got {size}", property="group_size")
    p = np.asarray(positions, np.float64)
    seg = np.asarray(segments, np.int64)
    n = len(p)
    if n == 0:
        return np.zeros(0, np.int64)
    order = np.lexsort((np.arange(n), seg))  # points of each segment together
    starts = np.flatnonzero(np.r_[True, seg[order][1:] != seg[order][:-1]])
    counts = np.diff(np.r_[starts, n])
    groups = -(-counts // size)
    while np.any(groups > 1):
        order, starts, counts, groups = _cut_round(p, order, starts, counts, groups)
    ids = np.empty(n, np.int64)
    ids[order] = np.repeat(np.arange(len(starts)), counts)
    return ids


def _cut_round(p, order, starts, counts, groups):
    """Cut every cell holding more than one group in two; cells stay in order, the lower
    half of a cut cell before its upper half."""
    n = len(order)
    cell_of = np.repeat(np.arange(len(starts)), counts)
    ordered = p[order]
    lo = np.minimum.reduceat(ordered, starts, axis=0)
    hi = np.maximum.reduceat(ordered, starts, axis=0)
    axis = np.argmax(hi - lo, axis=1)  # the first longest side on a tie
    cut = groups > 1
    coordinate = np.where(cut[cell_of], ordered[np.arange(n), axis[cell_of]], 0.0)
    rank = np.lexsort((order, coordinate, cell_of))  # cell, coordinate, input index
    order = order[rank]
    below_groups = (groups + 1) // 2
    below = np.where(cut, (counts * below_groups + groups // 2) // np.maximum(groups, 1), counts)
    below = np.clip(below, np.minimum(below_groups, 1), counts)
    new_counts = np.stack([below, counts - below], axis=1).reshape(-1)
    new_groups = np.stack([np.where(cut, below_groups, groups),
                           np.where(cut, groups - below_groups, 0)], axis=1).reshape(-1)
    keep = new_counts > 0
    new_counts, new_groups = new_counts[keep], new_groups[keep]
    new_starts = np.r_[0, np.cumsum(new_counts)[:-1]]
    return order, new_starts, new_counts, new_groups
