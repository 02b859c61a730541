"""From trained semantic features and 2D masks to one instance id per Gaussian.

Stage 2 gives each Gaussian a feature such that masks of one view render to features at least
the contrastive margin apart. Selecting by comparing a clicked pixel's feature with each
Gaussian's fails on real, translucent scenes: the pixel blends the object with what lies
behind it. So the features are used for what they do well, telling which masks of different
views show the same object, and the Gaussians take their instance from the masks themselves:

1. **Mask descriptors.** Each mask's mean rendered feature divided by its mean accumulated
   opacity (the feature per unit of opacity, so that a faint mask and an opaque one of the
   same object agree). Masks whose mean opacity is below :data:`MIN_MASK_ALPHA` (empty
   background) get none and cast no votes.
2. **Objects.** Masks are taken largest first; each joins the existing object whose centroid
   is nearest, if that distance is below ``join_distance`` (default half the contrastive
   margin) and the object holds no mask of the same view (two masks of one view are two
   instances by definition); otherwise it starts a new object. Centroids are pixel-weighted
   means of their masks' descriptors. Deterministic: ties keep view and mask order.
3. **Classification.** Each Gaussian (group) gets a score per object, started at
   -||f - c_o||^2 / :data:`SCORE_SCALE` (its feature's distance to the object's centroid) and
   refined by :data:`CLASSIFY_STEPS` Adam steps on the cross-entropy of every masked pixel:
   the pixel's rendered object probabilities (the compositing weights times each Gaussian's
   softmax, normalised) against its mask's object. A pixel already explained by the Gaussians
   in front of it pulls little on the faint ones behind, so what a Gaussian decides is what
   the masks show where it is visible (Gaussian Grouping classifies its rendered identity
   features the same way). Its instance is its best-scoring object.
4. **Neighbours.** Gaussians too faint to decide any pixel (their largest weight alpha * T in
   any training pixel is below :data:`DECIDING_WEIGHT`) take the majority among their
   :data:`NEIGHBOURS` nearest Gaussians (itself included), each weighing log(1 + 10 v), v its
   total rendered weight over the training views: objects are compact in space, the faint
   Gaussians' scores are not. Neighbours are approximate: candidates within :data:`WINDOW`
   places in three shifted Morton orders of the positions.

Measured on fruit_drops (24 views of 320x240, masks from its real labels, 0 ignored), click
3D / occlusion-aware 2D mIoU: nearest centroid 0.73 / 0.57; neighbour vote for every Gaussian
0.86 / 0.22 (it hands large card Gaussians to the letters in front of them); classification
0.74 / 0.78; classification and the faint Gaussians' vote 0.91 / 0.81. Voting with the masks'
pixels (each Gaussian's rendered weight per mask) gave 0.29 / 0.20: translucent letter
Gaussians spread most of their weight over pixels that show the card behind them.
5. **Prototypes.** Each instance's feature is the weighted mean feature of its Gaussians;
   instances are numbered 0..K-1 by decreasing Gaussian count (ties: first object first).

The result is exact to code (ids and K prototypes), so selection by instance survives
compression unchanged, and ``prototypes[ids]`` is a feature per Gaussian in the layout other
tools read (``ins_feat_*``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from csgs_codec.entropy.morton import MAX_BITS, morton_encode
from csgs_codec.errors import InputError
from csgs_codec.train.plain_adam import PlainAdam
from csgs_codec.train.semantic_batch import ViewBatch

#: Masks whose mean accumulated opacity is below this have no descriptor (nothing drawn).
MIN_MASK_ALPHA = 0.05
#: Squared feature distance that lowers a starting object score by 1 (feature units^2).
SCORE_SCALE = 1.0
#: Adam steps of the per-pixel classification, and their step size (fruit_drops, the
#: measurement in the module notes: 100 steps at 0.1 and 40 at 0.25 gave the same click mIoU,
#: 0.960 / 0.959, in 20.7 s and 10.9 s).
CLASSIFY_STEPS = 40
CLASSIFY_RATE = 0.25
#: A Gaussian whose largest weight alpha * T in any training pixel reaches this decides
#: pixels and keeps its classified instance; fainter ones take their neighbours' majority.
DECIDING_WEIGHT = 0.2
#: Gaussians whose instances vote for each Gaussian's instance (itself included).
NEIGHBOURS = 32
#: Candidates each side of a Gaussian in each Morton order when looking for neighbours.
WINDOW = 24
#: Rows of the candidate search handled at once (bounds memory).
NEIGHBOUR_CHUNK = 1 << 14


@dataclass(frozen=True)
class Instances:
    """Instance ids lifted from masks.

    Attributes:
        ids: (G,) int32 instance of each group in [0, K).
        prototypes: (K, D) float32 mean feature of each instance (feature units of stage 2).
        counts: (K,) int64 groups per instance.
        visibility: (G,) float64 total rendered weight of each group over the training
            views' masked pixels.
        objects: number of mask clusters found before empty ones were dropped.
        instance_objects: (K,) int64 the mask cluster each instance is.
        mask_objects: (M,) int64 the cluster of each mask of the batch, -1 for masks with
            no descriptor.
    """

    ids: np.ndarray
    prototypes: np.ndarray
    counts: np.ndarray
    visibility: np.ndarray
    objects: int
    instance_objects: np.ndarray
    mask_objects: np.ndarray

    @property
    def count(self) -> int:
        """K, the number of instances."""
        return int(self.prototypes.shape[0])

    def features(self) -> np.ndarray:
        """(G, D) float32 per-group features snapped to their instance's prototype."""
        return self.prototypes[self.ids]


def lift_instances(batch: ViewBatch, features: np.ndarray, positions: np.ndarray, *,
                   join_distance: float, neighbours: int = NEIGHBOURS) -> Instances:
    """Instance ids of the groups of ``batch`` from their trained features (module notes).

    Args:
        batch: the training views (:class:`ViewBatch`), the one the features were trained on.
        features: (G, D) float32 trained features (stage 2, feature units).
        positions: (G, 3) float positions of the groups.
        join_distance: largest descriptor distance at which a mask joins an object (feature
            units; half the contrastive margin is the natural choice).
        neighbours: Gaussians voting for each Gaussian's instance (1: no smoothing).

    Raises:
        InputError: shapes that disagree with the batch, a non-positive join distance or
            neighbour count.
    """
    groups = batch.matrix.shape[1]
    features = np.asarray(features, np.float32)
    if features.ndim != 2 or features.shape[0] != groups or not np.isfinite(features).all():
        raise InputError(f"features must be finite ({groups}, D), got {features.shape}",
                         property="features")
    positions = np.asarray(positions, np.float64)
    if positions.shape != (groups, 3) or not np.isfinite(positions).all():
        raise InputError(f"positions must be finite ({groups}, 3), got {positions.shape}",
                         property="positions")
    if not join_distance > 0:
        raise InputError(f"join distance must be positive, got {join_distance}",
                         property="join_distance")
    if isinstance(neighbours, bool) or not isinstance(neighbours, int) or neighbours < 1:
        raise InputError(f"neighbours must be a positive integer, got {neighbours!r}",
                         property="neighbours")
    descriptors, usable = _mask_descriptors(batch, features)
    centroids, mask_object = _join_masks(descriptors, usable, batch,
                                         float(join_distance) ** 2)
    if len(centroids) == 0:
        raise InputError("no mask covers any Gaussian: nothing to segment", property="masks")
    scores = -_squared_distances(features.astype(np.float64), centroids) / SCORE_SCALE
    ids = _classify(batch, mask_object, scores)
    visibility, peak = _visibility(batch)
    if neighbours > 1 and groups > 1:
        weight = np.log1p(10.0 * visibility) + 1e-3
        voted = _neighbour_vote(ids, weight, positions, min(neighbours, groups),
                                len(centroids))
        ids = np.where(peak >= DECIDING_WEIGHT, ids, voted)
    return _number_instances(ids, features, visibility, len(centroids), mask_object)


def _classify(batch: ViewBatch, mask_object: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """(G,) int64 best object of each group after the per-pixel cross-entropy refinement of
    the starting ``scores`` (G, objects) (module notes, step 3)."""
    device = batch.sizes.device
    row_object = torch.as_tensor(mask_object, device=device)[batch.mask_index]
    labelled = row_object >= 0
    target = row_object[labelled][:, None]
    logits = torch.as_tensor(scores, dtype=torch.float32, device=device).requires_grad_(True)
    if not bool(labelled.any()) or scores.shape[1] < 2:
        return np.argmax(scores, axis=1)
    optimizer = PlainAdam([logits], lr=CLASSIFY_RATE)
    for _ in range(CLASSIFY_STEPS):
        optimizer.zero_grad()
        rendered = batch.render(torch.softmax(logits, dim=1))[labelled]
        total = rendered.sum(dim=1, keepdim=True).clamp(min=1e-8)
        chosen = rendered.gather(1, target) / total
        loss = -torch.log(chosen.clamp(min=1e-8)).mean()
        loss.backward()
        optimizer.step()
    return logits.detach().argmax(dim=1).cpu().numpy()


def _squared_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) squared Euclidean distances, row by row in chunks."""
    out = np.empty((len(a), len(b)))
    for start in range(0, len(a), NEIGHBOUR_CHUNK):
        block = a[start:start + NEIGHBOUR_CHUNK]
        out[start:start + len(block)] = np.sum((block[:, None, :] - b[None]) ** 2, axis=2)
    return out


def _mask_descriptors(batch: ViewBatch, features: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """((M, D) float64 feature per unit opacity of each mask, (M,) bool has one)."""
    device = batch.sizes.device
    values = torch.as_tensor(features, device=device)
    with torch.no_grad():
        means = batch.mask_means(values).double().cpu().numpy()
        ones = torch.ones((values.shape[0], 1), dtype=values.dtype, device=device)
        alpha = batch.mask_means(ones).double().cpu().numpy()[:, 0]
    usable = alpha >= MIN_MASK_ALPHA
    descriptors = np.zeros_like(means)
    descriptors[usable] = means[usable] / alpha[usable, None]
    return descriptors, usable


def _join_masks(descriptors: np.ndarray, usable: np.ndarray, batch: ViewBatch,
                join_sq: float) -> tuple[np.ndarray, np.ndarray]:
    """((objects, D) float64 centroids of the masks joined into objects, (M,) int64 object
    of each mask, -1 without a descriptor) (module notes)."""
    sizes = batch.sizes.double().cpu().numpy()
    views = batch.mask_view.cpu().numpy()
    order = [int(m) for m in np.lexsort((np.arange(len(sizes)), -sizes)) if usable[m]]
    mask_object = np.full(len(sizes), -1, np.int64)
    sums: list[np.ndarray] = []
    weights: list[float] = []
    view_sets: list[set[int]] = []
    for m in order:
        best, best_distance = -1, np.inf
        if sums:
            centroids = np.stack(sums) / np.asarray(weights)[:, None]
            distance = np.sum((centroids - descriptors[m]) ** 2, axis=1)
            for k in np.argsort(distance, kind="stable"):
                if views[m] not in view_sets[k]:
                    best, best_distance = int(k), float(distance[k])
                    break
        if best >= 0 and best_distance < join_sq:
            sums[best] = sums[best] + sizes[m] * descriptors[m]
            weights[best] += sizes[m]
            view_sets[best].add(int(views[m]))
        else:
            best = len(sums)
            sums.append(sizes[m] * descriptors[m])
            weights.append(sizes[m])
            view_sets.append({int(views[m])})
        mask_object[m] = best
    if not sums:
        return np.zeros((0, descriptors.shape[1])), mask_object
    return np.stack(sums) / np.asarray(weights)[:, None], mask_object


def _visibility(batch: ViewBatch) -> tuple[np.ndarray, np.ndarray]:
    """((G,) float64 summed rendered weight of each group over the masked pixels, (G,)
    float64 its largest weight at one pixel)."""
    # The transpose's rows are the groups: its entries in order, without a COO copy.
    groups = batch.transpose.shape[0]
    counts = torch.diff(batch.transpose.crow_indices()).cpu().numpy()
    group = np.repeat(np.arange(groups), counts)
    weight = batch.transpose.values().double().cpu().numpy()
    peak = np.zeros(groups)
    np.maximum.at(peak, group, weight)
    return np.bincount(group, weights=weight, minlength=groups), peak


def approximate_neighbours(positions: np.ndarray, k: int) -> np.ndarray:
    """(N, k) int64 indices of (approximately) the k nearest points of each point, itself
    first: the nearest among candidates within :data:`WINDOW` places in three Morton orders
    of the positions shifted by 0, 1/3 and 2/3 of the scene's extent (shifted Z-orders: two
    points close in space are close in one of them unless a coarse cell boundary separates
    them in all three). Deterministic (stable sorts, ties by index)."""
    n = len(positions)
    low, high = positions.min(axis=0), positions.max(axis=0)
    span = float(np.max(high - low)) or 1.0
    cells = (positions - low) / span * (1 << (MAX_BITS - 2))
    ranks = []
    for shift in (0.0, 1 / 3, 2 / 3):
        grid = np.floor(cells + shift * (1 << (MAX_BITS - 2))).astype(np.uint64)
        order = np.argsort(morton_encode(grid), kind="stable")
        rank = np.empty(n, np.int64)
        rank[order] = np.arange(n)
        ranks.append((order, rank))
    offsets = np.arange(-WINDOW, WINDOW + 1)
    out = np.empty((n, k), np.int64)
    for start in range(0, n, NEIGHBOUR_CHUNK):
        rows = np.arange(start, min(start + NEIGHBOUR_CHUNK, n))
        candidates = np.concatenate(
            [order[np.clip(rank[rows][:, None] + offsets[None], 0, n - 1)]
             for order, rank in ranks], axis=1)
        candidates.sort(axis=1)
        repeated = np.zeros(candidates.shape, bool)
        repeated[:, 1:] = candidates[:, 1:] == candidates[:, :-1]
        d2 = np.sum((positions[candidates] - positions[rows][:, None]) ** 2, axis=2)
        d2[candidates == rows[:, None]] = -1.0  # the point itself comes first
        d2[repeated] = np.inf
        best = np.argsort(d2, axis=1, kind="stable")[:, :k]
        out[rows] = np.take_along_axis(candidates, best, axis=1)
    return out


def _neighbour_vote(ids: np.ndarray, weight: np.ndarray, positions: np.ndarray, k: int,
                    objects: int) -> np.ndarray:
    """Each group's id replaced by the weighted majority among its k neighbours."""
    neighbours = approximate_neighbours(positions, k)
    votes = np.zeros((len(ids), objects))
    rows = np.repeat(np.arange(len(ids)), k)
    np.add.at(votes, (rows, ids[neighbours].ravel()), weight[neighbours].ravel())
    return np.argmax(votes, axis=1)


def _number_instances(winner: np.ndarray, features: np.ndarray, visibility: np.ndarray,
                      objects: int, mask_objects: np.ndarray) -> Instances:
    """Instances numbered by decreasing group count, with visibility-weighted prototypes."""
    counts = np.bincount(winner, minlength=objects)
    kept = np.lexsort((np.arange(objects), -counts))
    kept = kept[counts[kept] > 0]
    renumber = np.full(objects, -1, np.int64)
    renumber[kept] = np.arange(kept.size)
    ids = renumber[winner].astype(np.int32)
    # Unseen groups weigh a little, so an instance of unseen groups only still has a mean.
    w = visibility + 1e-6
    sums = np.zeros((kept.size, features.shape[1]), np.float64)
    np.add.at(sums, ids, features.astype(np.float64) * w[:, None])
    totals = np.bincount(ids, weights=w, minlength=kept.size)
    prototypes = (sums / totals[:, None]).astype(np.float32)
    return Instances(ids, prototypes, counts[kept].astype(np.int64), visibility, objects,
                     kept.astype(np.int64), mask_objects)
