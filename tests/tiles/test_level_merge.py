"""Merging neighbouring Gaussians into coarser levels (csgs_codec.levels)."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.levels.groups import GROUP_SIZE, group_ids
from csgs_codec.levels.merge import (
    ALPHA_CAP,
    covariances,
    merge_groups,
    quaternions,
    rotation_matrices,
)
from csgs_codec.scene.gaussian_scene import GaussianScene
from tests.codec.helpers import random_scene


def test_groups_hold_at_most_eight_within_one_segment():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(1003, 3))
    segments = np.repeat([0, 1, 2], [500, 3, 500])
    ids = group_ids(p, segments)
    sizes = np.bincount(ids)
    assert sizes.max() <= GROUP_SIZE and sizes.min() >= 1
    assert ids.max() + 1 == 63 + 1 + 63  # ceil(n / 8) per segment
    for g in range(ids.max() + 1):
        assert len(np.unique(segments[ids == g])) == 1
    # numbered segment by segment
    assert np.all(np.diff([ids[segments == s].min() for s in range(3)]) > 0)
    assert np.array_equal(ids, group_ids(p.copy(), segments.copy()))


def test_groups_are_spatial_neighbours():
    # Two clusters far apart, 8 points each, in one segment: two groups, one per cluster.
    rng = np.random.default_rng(1)
    p = np.concatenate([rng.normal(size=(8, 3)), rng.normal(size=(8, 3)) + 100])
    ids = group_ids(p, np.zeros(16, int))
    assert len(set(ids[:8])) == 1 and len(set(ids[8:])) == 1 and ids[0] != ids[8]


def test_a_group_of_one_is_its_gaussian():
    scene = random_scene(200, sh_degree=2, seed=4)
    merged, _ = merge_groups(scene, np.arange(200))
    assert np.allclose(merged.positions, scene.positions, atol=1e-6)
    assert np.allclose(merged.sh_rest, scene.sh_rest, atol=1e-6)
    keep = 1 / (1 + np.exp(-scene.opacity)) < ALPHA_CAP
    assert np.allclose(merged.opacity[keep], scene.opacity[keep], atol=1e-4)
    a = covariances(scene.rotations, np.exp(scene.scales.astype(np.float64)))
    b = covariances(merged.rotations, np.exp(merged.scales.astype(np.float64)))
    assert np.allclose(a, b, rtol=1e-4, atol=1e-12)


def test_two_gaussians_merge_to_their_moments():
    scene = GaussianScene(
        positions=np.array([[0, 0, 0], [2, 0, 0]], np.float32),
        sh_dc=np.array([[1, 0, 0], [0, 1, 0]], np.float32),
        sh_rest=np.zeros((2, 0, 3), np.float32),
        opacity=np.zeros(2, np.float32),  # alpha 0.5 each
        scales=np.log(np.full((2, 3), 0.1, np.float32)),
        rotations=np.array([[1, 0, 0, 0]] * 2, np.float32))
    m, seen = merge_groups(scene, np.zeros(2, np.int64))
    assert seen.tolist() == [0.0]
    assert np.allclose(m.positions, [[1, 0, 0]])
    assert np.allclose(m.sh_dc, [[0.5, 0.5, 0]])
    cov = covariances(m.rotations, np.exp(m.scales.astype(np.float64)))[0]
    assert np.allclose(cov, np.diag([0.01 + 1.0, 0.01, 0.01]), rtol=1e-5)
    # mass kept: 2 x 0.5 x 0.01 over the merged footprint sqrt(1.01) x 0.1
    alpha = 1 / (1 + np.exp(-m.opacity[0]))
    assert alpha == pytest.approx(0.01 / (np.sqrt(1.01) * 0.1), rel=1e-5)


def test_semantic_rows_and_labels_come_from_the_heaviest_instance():
    scene = random_scene(6, seed=5, semantic=2, labels=True)
    scene.opacity[:] = 0.0
    scene.scales[:] = np.log(0.1)
    scene.scales[3:] = np.log(0.2)  # instance B's members weigh 4x as much
    rows = np.array([[1, 0]] * 3 + [[0, 1]] * 3, np.float32)
    scene.semantic = rows
    scene.labels = np.array([7, 7, 7, 9, 9, 9], np.int32)
    keep = np.array([0, 1, 2, 3])  # three of A, one of B (weighs 4): B wins 4 to 3
    m, _ = merge_groups(scene.subset(keep), np.zeros(4, np.int64))
    assert np.array_equal(m.semantic, [[0, 1]]) and m.labels.tolist() == [9]
    m, _ = merge_groups(scene.subset(np.array([0, 1, 2])), np.zeros(3, np.int64))
    assert np.array_equal(m.semantic, [[1, 0]]) and m.labels.tolist() == [7]


def test_quaternions_round_trip_rotations():
    q = np.random.default_rng(6).normal(size=(500, 4))
    r = rotation_matrices(q)
    back = quaternions(r)
    assert np.all(back[:, 0] >= 0)
    assert np.allclose(rotation_matrices(back), r, atol=1e-12)
    # 180-degree turns (w = 0) too
    flips = rotation_matrices(np.array([[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
    assert np.allclose(rotation_matrices(quaternions(flips)), flips, atol=1e-12)


def test_colours_follow_what_the_views_see():
    """A group whose front member is seen and whose back member is hidden takes the front
    one's colour; a group nobody sees falls back to footprint weights; visibility adds up."""
    scene = GaussianScene(
        positions=np.zeros((4, 3), np.float32), sh_dc=np.array(
            [[1, 0, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0]], np.float32),
        sh_rest=np.zeros((4, 0, 3), np.float32), opacity=np.zeros(4, np.float32),
        scales=np.log(np.full((4, 3), 0.1, np.float32)),
        rotations=np.array([[1, 0, 0, 0]] * 4, np.float32))
    groups = np.array([0, 0, 1, 1])
    merged, seen = merge_groups(scene, groups, np.array([5.0, 0.0, 0.0, 0.0]))
    assert np.allclose(merged.sh_dc, [[1, 0, 0], [0.5, 0.5, 0]])
    assert seen.tolist() == [5.0, 0.0]
