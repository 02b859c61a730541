"""Seeded synthetic Scaffold-GS anchor scenes with known object labels, for tests.

Each object is a blob of anchors on a voxel grid with one label and one semantic direction
(plus small noise). Anchor features are low-rank plus noise: a few scene-wide factors load on
every channel and one factor per channel group loads only on its group, so the channel groups
are correlated with each other and within themselves (something a channel-wise autoregressive
entropy model can exploit). The MLP weights are random but keep most Gaussians visible.
Values depend only on the arguments (numpy's PCG64 generator).
"""

from __future__ import annotations

import numpy as np

from csgs_codec.scene.anchor_scene import (
    DEFAULT_FEAT_DIM,
    DEFAULT_N_OFFSETS,
    DEFAULT_SEMANTIC_DIM,
    AnchorScene,
    MLPWeights,
    ScaffoldMLPWeights,
    default_semantic_names,
)


def synthetic_mlps(feat_dim: int = DEFAULT_FEAT_DIM, n_offsets: int = DEFAULT_N_OFFSETS, *,
                   seed: int = 0, use_distance: bool = True,
                   appearance: tuple[int, int] | None = None) -> ScaffoldMLPWeights:
    """Random Scaffold-GS heads for F features and K offsets (hidden width F).

    Initialised like ``nn.Linear`` (uniform in +-1/sqrt(fan_in)), then biased so opacities
    are mostly positive and quaternions lean towards identity.

    Args:
        use_distance: every head takes the distance input (HAC / CSGaussian layout).
        appearance: (cameras C, width A) for an appearance table, or None.
    """
    rng = np.random.default_rng([seed, 1])
    extra = int(use_distance)
    a_dim = 0 if appearance is None else appearance[1]

    def head(in_dim: int, out_dim: int) -> MLPWeights:
        def uniform(shape: tuple[int, ...], fan_in: int) -> np.ndarray:
            bound = 1.0 / np.sqrt(fan_in)
            return rng.uniform(-bound, bound, shape).astype(np.float32)

        return MLPWeights(uniform((feat_dim, in_dim), in_dim), uniform((feat_dim,), in_dim),
                          uniform((out_dim, feat_dim), feat_dim),
                          uniform((out_dim,), feat_dim))

    opacity = head(feat_dim + 3 + extra, n_offsets)
    opacity.b2 += np.float32(0.6)
    cov = head(feat_dim + 3 + extra, 7 * n_offsets)
    cov.b2.reshape(n_offsets, 7)[:, 3] += np.float32(1.0)
    color = head(feat_dim + 3 + extra + a_dim, 3 * n_offsets)
    table = None
    if appearance is not None:
        table = (0.1 * rng.standard_normal(appearance)).astype(np.float32)
    return ScaffoldMLPWeights(opacity=opacity, cov=cov, color=color, appearance=table)


def synthetic_anchor_scene(n_objects: int = 5, anchors_per_object: int = 200, *,
                           feat_dim: int = DEFAULT_FEAT_DIM, n_offsets: int = DEFAULT_N_OFFSETS,
                           semantic_dim: int = DEFAULT_SEMANTIC_DIM, feature_groups: int = 5,
                           voxel_size: float = 0.01, masked_fraction: float = 0.2,
                           semantic_noise: float = 0.05, seed: int = 0,
                           with_mlps: bool = True) -> AnchorScene:
    """A labelled anchor scene: ``n_objects`` blobs of ``anchors_per_object`` anchors each.

    Args:
        n_objects: number of objects; labels are 0..n_objects-1 (int32).
        anchors_per_object: anchors in each object (distinct voxels).
        feat_dim, n_offsets, semantic_dim: F, K and S.
        feature_groups: channel groups with their own extra factor (F split evenly).
        voxel_size: grid step of the anchor positions, world units.
        masked_fraction: share of offsets masked out (drawn independently).
        semantic_noise: standard deviation of the noise added to each object's unit
            semantic direction.
        seed: everything is a function of the arguments.
        with_mlps: attach :func:`synthetic_mlps` weights.

    Returns:
        the validated scene, anchors grouped by object.
    """
    rng = np.random.default_rng([seed, 0])
    radius = voxel_size * (3.0 * anchors_per_object / (4.0 * np.pi) * 2.0) ** (1.0 / 3.0)
    spacing = 3.5 * radius
    side = int(np.ceil(np.sqrt(n_objects)))
    centres = np.array([[(i % side) * spacing, (i // side) * spacing, 0.0]
                        for i in range(n_objects)])
    centres += rng.uniform(-0.2, 0.2, centres.shape) * radius
    positions, labels = [], []
    for obj, centre in enumerate(centres):
        voxels = np.zeros((0, 3), np.int64)
        while len(voxels) < anchors_per_object:
            direction = rng.standard_normal((4 * anchors_per_object, 3))
            direction /= np.linalg.norm(direction, axis=1, keepdims=True)
            r = radius * rng.uniform(0, 1, (len(direction), 1)) ** (1 / 3)
            cells = np.round((centre + direction * r * [1.0, 0.8, 0.6]) / voxel_size)
            voxels = np.concatenate([voxels, cells.astype(np.int64)])
            _, first = np.unique(voxels, axis=0, return_index=True)
            voxels = voxels[np.sort(first)]
        positions.append(voxels[:anchors_per_object] * voxel_size)
        labels.append(np.full(anchors_per_object, obj, np.int32))
    pos = np.concatenate(positions).astype(np.float32)
    lab = np.concatenate(labels)
    m = len(pos)

    features = _correlated_features(rng, pos.astype(np.float64), lab, n_objects, feat_dim,
                                     feature_groups, radius)
    directions = rng.standard_normal((max(n_objects, semantic_dim), semantic_dim))
    if n_objects <= semantic_dim:
        directions = np.linalg.qr(directions.T)[0].T  # orthonormal rows
    directions = directions[:n_objects] / np.linalg.norm(directions[:n_objects], axis=1,
                                                         keepdims=True)
    semantic = directions[lab] + semantic_noise * rng.standard_normal((m, semantic_dim))
    offsets = rng.uniform(-1.5, 1.5, (m, n_offsets, 3))
    scaling = np.concatenate([
        np.log(voxel_size) + 0.1 * rng.standard_normal((m, 3)),
        np.log(0.5 * voxel_size) + 0.2 * rng.standard_normal((m, 3))], axis=1)
    mask = rng.uniform(0, 1, (m, n_offsets)) >= masked_fraction
    scene = AnchorScene(
        positions=pos, features=features.astype(np.float32),
        offsets=offsets.astype(np.float32), scaling=scaling.astype(np.float32),
        offset_mask=mask, semantic=semantic.astype(np.float32),
        semantic_names=default_semantic_names(semantic_dim), labels=lab,
        mlps=synthetic_mlps(feat_dim, n_offsets, seed=seed) if with_mlps else None)
    scene.validate()
    return scene


def _correlated_features(rng: np.random.Generator, pos: np.ndarray, labels: np.ndarray,
                         n_objects: int, feat_dim: int, groups: int,
                         radius: float) -> np.ndarray:
    """(M, F) features = shared factors @ loadings + per-group factor + noise."""
    m, rank = len(pos), 4
    object_code = rng.standard_normal((n_objects, rank))
    waves = rng.standard_normal((3, rank)) / radius
    shared = object_code[labels] + 0.5 * np.sin(pos @ waves) + 0.3 * rng.standard_normal((m, rank))
    out = shared @ (rng.standard_normal((rank, feat_dim)) / np.sqrt(rank))
    bounds = np.linspace(0, feat_dim, groups + 1).round().astype(int)
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        factor = rng.standard_normal((m, 1))
        out[:, lo:hi] += 0.6 * factor * rng.standard_normal((1, hi - lo))
    return out + 0.1 * rng.standard_normal((m, feat_dim))
