"""Merging groups of Gaussians into one each, keeping what a distant view sees of them.

Every Gaussian i weighs w_i = alpha_i * a_i: its opacity times the area of its largest cross
-section (a_i = s_1 s_2, its two largest scales; pi left out, it cancels). A group becomes one
Gaussian whose

- centre and covariance are the group's weighted first and second moments: mu = sum w_i mu_i /
  W and Sigma = sum w_i (Sigma_i + (mu_i - mu)(mu_i - mu)^T) / W (W = sum w_i);
- colour is the mean of every SH coefficient (DC and rest) weighted by how much of the views
  each member makes (``visibility``, its blending weights summed over a set of views), so a
  group's hidden members (the inside of a surface) do not tint what is seen of it; a group
  no view sees takes the weights above;
- opacity keeps the group's opacity mass: alpha = min(W / a, ALPHA_CAP), a from the merged
  scales as a_i from a member's (a group of one is that Gaussian, up to rounding);
- semantic row (feature vector) and label are those of the group's heaviest instance (by the
  colour weights): the distinct feature row (label) whose members weigh most together, the
  smallest on a tie, so merged features stay among the scene's own rows (an instance
  codebook stays one).

Arithmetic in float64; the result is rounded to float32 once.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.scene.gaussian_scene import GaussianScene

#: Highest opacity a merged Gaussian gets (a merged group that covers its footprint fully
#: would otherwise reach 1, whose logit is infinite).
ALPHA_CAP = 0.995
#: Smallest weight a Gaussian counts with (a fully transparent group still merges).
MIN_WEIGHT = 1e-30


def merge_groups(scene: GaussianScene, groups: np.ndarray,
                 visibility: np.ndarray | None = None) -> tuple[GaussianScene, np.ndarray]:
    """The scene of ``groups`` (N,) int64 ids 0..G-1 (every id present) of ``scene``'s
    Gaussians merged, one Gaussian per group in id order (semantic names and instance table
    carried over), and each merged Gaussian's visibility (G,): its members' summed.

    Args:
        visibility: (N,) >= 0, how much each Gaussian shows in a set of views (blending
            weights summed, pixels), or None (all alike: colours by footprint weight).
    """
    g = np.asarray(groups, np.int64)
    count = int(g.max()) + 1 if len(g) else 0
    with np.errstate(over="ignore"):  # exp(-logit) overflows below -709: alpha 0
        alpha = 1.0 / (1.0 + np.exp(-scene.opacity.astype(np.float64)))
    scales = np.exp(scene.scales.astype(np.float64))
    weight = np.maximum(alpha * footprint_area(scales), MIN_WEIGHT)
    total = np.bincount(g, weight, count)
    seen = np.zeros(len(g)) if visibility is None else np.asarray(visibility, np.float64)
    seen_total = np.bincount(g, seen, count)
    colour_weight = np.where(seen_total[g] > 0, seen, weight)
    colour_total = np.bincount(g, colour_weight, count)

    def mean(values: np.ndarray, w: np.ndarray = weight, sums: np.ndarray = total
             ) -> np.ndarray:
        flat = values.reshape(len(values), -1).astype(np.float64)
        out = np.stack([np.bincount(g, w * flat[:, k], count)
                        for k in range(flat.shape[1])], axis=1) if flat.shape[1] else (
            np.zeros((count, 0)))
        return (out / sums[:, None]).reshape((count,) + values.shape[1:])

    centre = mean(scene.positions)
    spread = scene.positions.astype(np.float64) - centre[g]
    covariance = covariances(scene.rotations, scales) + spread[:, :, None] * spread[:, None, :]
    merged_cov = mean(covariance)
    merged_scales, merged_rotations = decompose(merged_cov)
    merged_alpha = np.minimum(total / footprint_area(merged_scales), ALPHA_CAP)
    rows = heaviest_rows(scene, g, colour_weight, count)
    merged = GaussianScene(
        positions=centre.astype(np.float32),
        sh_dc=mean(scene.sh_dc, colour_weight, colour_total).astype(np.float32),
        sh_rest=mean(scene.sh_rest, colour_weight, colour_total).astype(np.float32),
        opacity=np.log(merged_alpha / (1.0 - merged_alpha)).astype(np.float32),
        scales=np.log(merged_scales).astype(np.float32),
        rotations=merged_rotations.astype(np.float32),
        semantic=None if scene.semantic is None else scene.semantic[rows],
        semantic_names=scene.semantic_names,
        labels=None if scene.labels is None else scene.labels[
            _label_rows(scene, g, colour_weight, count)],
        instances=scene.instances,
    )
    return merged, seen_total


def footprint_area(scales: np.ndarray) -> np.ndarray:
    """(N,) product of the two largest of each row of ``scales`` (N, 3) linear units."""
    s = np.sort(scales, axis=1)
    return s[:, 1] * s[:, 2]


def covariances(rotations: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """(N, 3, 3) float64 R diag(s^2) R^T of quaternions ``rotations`` (N, 4) w, x, y, z
    (normalized here; a zero quaternion is the identity) and linear ``scales`` (N, 3)."""
    r = rotation_matrices(rotations)
    return np.einsum("nij,nj,nkj->nik", r, scales * scales, r)


def rotation_matrices(rotations: np.ndarray) -> np.ndarray:
    """(N, 3, 3) float64 rotation matrices of quaternions (N, 4) w, x, y, z."""
    q = np.asarray(rotations, np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), np.array([1.0, 0, 0, 0]))
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


def decompose(covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scales (G, 3) linear (the square roots of the eigenvalues, floored at 1e-12 of the
    largest) and unit quaternions (G, 4) w, x, y, z (w >= 0) of covariances (G, 3, 3)."""
    values, vectors = np.linalg.eigh(covariance)
    floor = np.maximum(values[:, 2:], 1e-300) * 1e-24
    scales = np.sqrt(np.maximum(values, floor))
    flip = np.linalg.det(vectors) < 0
    vectors[flip, :, 0] *= -1  # a proper rotation: det +1
    return scales, quaternions(vectors)


def quaternions(matrices: np.ndarray) -> np.ndarray:
    """(G, 4) unit quaternions w, x, y, z (w >= 0) of rotation matrices (G, 3, 3), by the
    largest of the four diagonal combinations (stable for every rotation)."""
    m = matrices
    t = np.stack([1 + m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2],
                  1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2],
                  1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2],
                  1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2]], axis=1)
    pick = np.argmax(t, axis=1)
    s = np.sqrt(np.maximum(t[np.arange(len(m)), pick], 1e-300)) * 2  # 4 * the picked part
    q = np.empty((len(m), 4))
    cases = (
        (m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]),
        (m[:, 2, 1] - m[:, 1, 2], m[:, 0, 1] + m[:, 1, 0], m[:, 0, 2] + m[:, 2, 0]),
        (m[:, 0, 2] - m[:, 2, 0], m[:, 0, 1] + m[:, 1, 0], m[:, 1, 2] + m[:, 2, 1]),
        (m[:, 1, 0] - m[:, 0, 1], m[:, 0, 2] + m[:, 2, 0], m[:, 1, 2] + m[:, 2, 1]),
    )
    for k, (a, b, c) in enumerate(cases):
        sel = pick == k
        others = [a[sel] / s[sel], b[sel] / s[sel], c[sel] / s[sel]]
        slots = [i for i in range(4) if i != k]
        q[sel, k] = s[sel] / 4
        for slot, value in zip(slots, others):
            q[sel, slot] = value
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def heaviest_rows(scene: GaussianScene, groups: np.ndarray, weight: np.ndarray,
                  count: int) -> np.ndarray:
    """(G,) the row of ``scene`` whose semantic feature row is the heaviest in each group
    (an arbitrary member where the scene has no features)."""
    if scene.semantic is None:
        return np.zeros(count, np.int64)
    _, kind = np.unique(scene.semantic, axis=0, return_inverse=True)
    return _heaviest(groups, kind.reshape(-1), weight, count)


def _label_rows(scene: GaussianScene, groups, weight, count) -> np.ndarray:
    return _heaviest(groups, np.asarray(scene.labels, np.int64), weight, count)


def _heaviest(groups: np.ndarray, kind: np.ndarray, weight: np.ndarray, count: int
              ) -> np.ndarray:
    """(G,) per group, the first row (in input order) of the kind whose rows weigh most in
    the group together (the smallest kind on a tie)."""
    n = len(groups)
    pair_order = np.lexsort((np.arange(n), kind, groups))
    g, k = groups[pair_order], kind[pair_order]
    new = np.r_[True, (g[1:] != g[:-1]) | (k[1:] != k[:-1])]
    starts = np.flatnonzero(new)
    pair_weight = np.add.reduceat(weight[pair_order], starts)
    pair_group = g[starts]
    first_row = pair_order[starts]
    # per group the heaviest pair: sort by group, then weight descending, then kind
    best = np.lexsort((k[starts], -pair_weight, pair_group))
    group_first = np.r_[True, pair_group[best][1:] != pair_group[best][:-1]]
    out = np.zeros(count, np.int64)
    out[pair_group[best][group_first]] = first_row[best][group_first]
    return out
