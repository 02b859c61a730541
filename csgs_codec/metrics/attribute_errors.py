"""Per-attribute errors between two scenes holding the same Gaussians in any order.

Matching (reference row i is paired with candidate row ``index[i]``):

1. same positions in the same order, bit for bit: identity;
2. the same multiset of positions: both scenes are sorted by (x, y, z) and paired rank by rank
   (Gaussians sharing a position keep their file order, so duplicates pair in file order);
3. otherwise each reference Gaussian is paired with its nearest candidate by Euclidean
   distance (exact nearest neighbour, found on a uniform grid). This pairing need not be
   one-to-one; :class:`Matching` says how many candidates nobody picked. When positions moved
   by more than half the gap between neighbouring Gaussians (coarse quantisation), neighbours
   can pair with each other's copies, and the errors then overstate the attribute loss: read
   them as upper bounds, with ``unpicked_candidates`` as the sign of how often it happened.

Errors are absolute differences of the stored values (positions in world units, SH
coefficients, opacity logits, log-scales), except rotations, which are normalised and sign
aligned first (q and -q are the same rotation). SH bands present in only one scene count
against zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.scene.gaussian_scene import GaussianScene

#: Largest number of (query, point) pairs held in memory at once by the grid search.
_PAIR_BUDGET = 1 << 22
#: Mean number of points in a point's own cell the grid aims for.
_TARGET_OCCUPANCY = 4.0


@dataclass(frozen=True)
class Matching:
    """How reference Gaussians were paired with candidate Gaussians.

    Attributes:
        index: (N_reference,) int64, the candidate row paired with each reference row.
        method: "identity", "exact position" or "nearest neighbour".
        max_distance: largest distance between paired positions, world units.
        unpicked_candidates: candidate rows paired with no reference row.
    """

    index: np.ndarray
    method: str
    max_distance: float
    unpicked_candidates: int


def match_gaussians(reference: np.ndarray, candidate: np.ndarray) -> Matching:
    """Pair rows of ``reference`` (N, 3) with rows of ``candidate`` (M, 3) positions."""
    ref = np.asarray(reference, dtype=np.float64)
    cand = np.asarray(candidate, dtype=np.float64)
    if len(ref) == 0 or len(cand) == 0:
        return Matching(np.zeros(0, np.int64), "identity", 0.0, len(cand))
    if ref.shape == cand.shape and np.array_equal(ref, cand):
        return Matching(np.arange(len(ref)), "identity", 0.0, 0)
    if ref.shape == cand.shape:
        ref_order = np.lexsort(ref.T[::-1])
        cand_order = np.lexsort(cand.T[::-1])
        if np.array_equal(ref[ref_order], cand[cand_order]):
            index = np.empty(len(ref), np.int64)
            index[ref_order] = cand_order
            return Matching(index, "exact position", 0.0, 0)
    index, distance = nearest_neighbours(ref, cand)
    unpicked = len(cand) - len(np.unique(index))
    return Matching(index, "nearest neighbour", float(distance.max()), unpicked)


def attribute_errors(reference: GaussianScene, candidate: GaussianScene
                     ) -> tuple[dict[str, dict[str, float]], Matching]:
    """Max and mean absolute error per attribute after matching the Gaussians.

    Returns:
        ({attribute: {"max_abs", "mean_abs", "channels"}}, matching). Attributes: positions,
        sh_dc, sh_rest (when either scene has SH bands), opacity, scales, rotations, and
        semantic when both scenes carry the same number of semantic channels.
    """
    matching = match_gaussians(reference.positions, candidate.positions)
    paired = matching.index
    pairs = {
        "positions": (reference.positions, candidate.positions[paired]),
        "sh_dc": (reference.sh_dc, candidate.sh_dc[paired]),
        "opacity": (reference.opacity[:, None], candidate.opacity[paired][:, None]),
        "scales": (reference.scales, candidate.scales[paired]),
        "rotations": _aligned_rotations(reference.rotations, candidate.rotations[paired]),
    }
    if reference.sh_rest.shape[1] or candidate.sh_rest.shape[1]:
        pairs["sh_rest"] = _padded_sh_rest(reference.sh_rest, candidate.sh_rest[paired])
    if (reference.semantic is not None and candidate.semantic is not None
            and reference.semantic.shape[1] == candidate.semantic.shape[1]):
        pairs["semantic"] = (reference.semantic, candidate.semantic[paired])
    errors = {}
    for name, (a, b) in pairs.items():
        diff = np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64))
        diff = diff.reshape(len(diff), -1)
        empty = diff.size == 0
        errors[name] = {"max_abs": 0.0 if empty else float(diff.max()),
                        "mean_abs": 0.0 if empty else float(diff.mean()),
                        "channels": int(diff.shape[1])}
    return errors, matching


def nearest_neighbours(queries: np.ndarray, points: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Exact nearest point for each query: (index (M,) int64, distance (M,) float64).

    Uniform grid search: a query whose best distance within its 3x3x3 cell block is at most
    the cell size has found its true nearest point (anything nearer lies in that block); the
    others are searched again with cells twice as large.
    """
    queries = np.asarray(queries, np.float64)
    points = np.asarray(points, np.float64)
    best_index = np.full(len(queries), -1, np.int64)
    best_d2 = np.full(len(queries), np.inf)
    cell = _initial_cell_size(points)
    pending = np.arange(len(queries))
    while len(pending):
        while np.prod((np.ptp(points, axis=0) / cell + 5).astype(np.float64)) > 2.0**62:
            cell *= 2.0  # keep the int64 cell keys from overflowing on far-flung floaters
        grid = _Grid(points, cell)
        for offset in np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1]), -1).reshape(-1, 3):
            grid.search(queries, pending, offset, best_index, best_d2)
        pending = pending[best_d2[pending] > cell * cell]
        cell *= 2.0
    return best_index, np.sqrt(best_d2)


def _initial_cell_size(points: np.ndarray) -> float:
    low, high = np.percentile(points, 1, axis=0), np.percentile(points, 99, axis=0)
    extent = float(np.max(high - low))
    if not extent > 0:
        extent = float(np.max(np.ptp(points, axis=0))) or 1.0
    cell = extent / max(len(points), 1) ** (1 / 3)
    for _ in range(12):  # shrink until dense clusters no longer crowd single cells
        keys = _Grid(points, cell).sorted_keys
        counts = np.diff(np.flatnonzero(np.r_[True, keys[1:] != keys[:-1], True]))
        if np.sum(counts.astype(np.float64) ** 2) / len(points) <= _TARGET_OCCUPANCY:
            break
        cell /= 2.0
    return cell


class _Grid:
    """Points bucketed into cubic cells, cells addressed by one int64 key."""

    def __init__(self, points: np.ndarray, cell: float) -> None:
        self.points, self.cell = points, cell
        self.origin = points.min(axis=0) - 2 * cell
        coords = np.floor((points - self.origin) / cell).astype(np.int64)
        self.dims = coords.max(axis=0) + 3
        self.order = np.argsort(self._key(coords), kind="stable")
        self.sorted_keys = self._key(coords)[self.order]

    def _key(self, coords: np.ndarray) -> np.ndarray:
        return (coords[:, 0] * self.dims[1] + coords[:, 1]) * self.dims[2] + coords[:, 2]

    def search(self, queries: np.ndarray, pending: np.ndarray, offset: np.ndarray,
               best_index: np.ndarray, best_d2: np.ndarray) -> None:
        """Improve best_index / best_d2 of ``pending`` queries from one neighbouring cell."""
        coords = np.floor((queries[pending] - self.origin) / self.cell).astype(np.int64) + offset
        inside = np.all((coords >= 0) & (coords < self.dims), axis=1)
        keys = np.where(inside, self._key(np.clip(coords, 0, self.dims - 1)), -1)
        start = np.searchsorted(self.sorted_keys, keys, side="left")
        counts = np.where(inside, np.searchsorted(self.sorted_keys, keys, side="right") - start,
                          0)
        cumulative = np.cumsum(counts)
        # Chunks end at query boundaries, each holding about _PAIR_BUDGET pairs.
        ends = np.searchsorted(cumulative, np.arange(_PAIR_BUDGET, cumulative[-1], _PAIR_BUDGET),
                               side="right")
        begin = 0
        for end in np.unique(np.append(ends, len(pending))):
            self._search_chunk(queries, pending[begin:end], start[begin:end],
                               counts[begin:end], best_index, best_d2)
            begin = end

    def _search_chunk(self, queries, pending, start, counts, best_index, best_d2) -> None:
        total = int(counts.sum())
        if total == 0:
            return
        query_rows = np.repeat(pending, counts)
        first = np.repeat(np.cumsum(counts) - counts, counts)
        slots = np.repeat(start, counts) + np.arange(total) - first
        point_rows = self.order[slots]
        d2 = np.sum((queries[query_rows] - self.points[point_rows]) ** 2, axis=1)
        # Pairs come grouped by query: the minimum of each group, then its first position.
        nonzero = counts > 0
        group_start = (np.cumsum(counts) - counts)[nonzero]
        group_min = np.minimum.reduceat(d2, group_start)
        hits = np.flatnonzero(d2 == np.repeat(group_min, counts[nonzero]))
        leaders = hits[np.searchsorted(hits, group_start)]
        rows, d2_best = pending[nonzero], group_min
        better = d2_best < best_d2[rows]
        best_d2[rows[better]] = d2_best[better]
        best_index[rows[better]] = point_rows[leaders][better]


def _aligned_rotations(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    a = a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-30)
    b = b / np.maximum(np.linalg.norm(b, axis=1, keepdims=True), 1e-30)
    sign = np.where(np.sum(a * b, axis=1, keepdims=True) < 0, -1.0, 1.0)
    return a, b * sign


def _padded_sh_rest(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    bands = max(a.shape[1], b.shape[1])
    pad = lambda x: np.pad(x, ((0, 0), (0, bands - x.shape[1]), (0, 0)))  # noqa: E731
    return pad(a), pad(b)
