"""Per-attribute errors: Gaussians matched by identity, exact position or nearest neighbour."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.metrics.attribute_errors import (
    attribute_errors,
    match_gaussians,
    nearest_neighbours,
)
from tests.render.synthetic import blob_scene


def shuffled(scene, seed=1):
    order = np.random.default_rng(seed).permutation(len(scene))
    return scene.subset(order), order


def test_identical_scenes_match_by_identity_with_zero_errors():
    scene = blob_scene(sh_degree=1)
    errors, matching = attribute_errors(scene, scene.subset(np.arange(len(scene))))
    assert matching.method == "identity"
    assert set(errors) == {"positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations"}
    assert all(e["max_abs"] == 0 and e["mean_abs"] == 0 for e in errors.values())


def test_reordered_scene_matches_by_exact_position():
    scene = blob_scene()
    candidate, order = shuffled(scene)
    matching = match_gaussians(scene.positions, candidate.positions)
    assert matching.method == "exact position"
    np.testing.assert_array_equal(order[matching.index], np.arange(len(scene)))


def test_attribute_error_is_the_change_made_to_that_attribute():
    scene = blob_scene()
    candidate, order = shuffled(scene)
    candidate.sh_dc[:, 1] += 0.25
    candidate.opacity[order == 7] -= 1.5  # one known Gaussian
    errors, _ = attribute_errors(scene, candidate)
    assert errors["sh_dc"]["max_abs"] == pytest.approx(0.25, abs=1e-6)
    assert errors["sh_dc"]["mean_abs"] == pytest.approx(0.25 / 3, abs=1e-6)
    assert errors["opacity"]["max_abs"] == pytest.approx(1.5, abs=1e-6)
    assert errors["opacity"]["mean_abs"] == pytest.approx(1.5 / len(scene), abs=1e-6)
    assert errors["positions"]["max_abs"] == 0 and errors["scales"]["max_abs"] == 0


def test_moved_positions_match_by_nearest_neighbour():
    scene = blob_scene(count=2000)
    candidate, order = shuffled(scene)
    rng = np.random.default_rng(5)
    candidate.positions += rng.uniform(-1e-4, 1e-4, size=candidate.positions.shape)
    errors, matching = attribute_errors(scene, candidate)
    assert matching.method == "nearest neighbour"
    np.testing.assert_array_equal(order[matching.index], np.arange(len(scene)))
    assert errors["positions"]["max_abs"] <= 1e-4 + 1e-7
    assert matching.max_distance <= np.sqrt(3) * 1e-4 + 1e-7
    assert errors["sh_dc"]["max_abs"] == 0


def test_rotation_error_ignores_sign_and_norm():
    scene = blob_scene()
    candidate = scene.subset(np.arange(len(scene)))
    candidate.rotations[::2] *= -3.0
    errors, _ = attribute_errors(scene, candidate)
    assert errors["rotations"]["max_abs"] == pytest.approx(0, abs=1e-7)


def test_missing_sh_bands_count_against_zero():
    scene = blob_scene(sh_degree=1)
    scene.sh_rest[:] = 0.5
    candidate = blob_scene(sh_degree=0)
    errors, _ = attribute_errors(scene, candidate)
    assert errors["sh_rest"] == {"max_abs": 0.5, "mean_abs": 0.5, "channels": 9}


def test_semantic_errors_reported_when_both_have_features():
    scene = blob_scene(count=50)
    scene.semantic = np.zeros((50, 2), np.float32)
    scene.semantic_names = ("sem_0", "sem_1")
    candidate = scene.subset(np.arange(50))
    candidate.semantic = scene.semantic + 0.125
    errors, _ = attribute_errors(scene, candidate)
    assert errors["semantic"]["max_abs"] == pytest.approx(0.125)


def test_nearest_neighbours_equal_brute_force_with_floaters():
    rng = np.random.default_rng(11)
    points = np.concatenate([rng.normal(size=(3000, 3)) * [1, 1, 0.01],
                             rng.uniform(-500, 500, size=(20, 3))])
    queries = np.concatenate([rng.normal(size=(300, 3)), rng.uniform(-900, 900, size=(30, 3))])
    index, distance = nearest_neighbours(queries, points)
    brute = np.linalg.norm(queries[:, None] - points[None], axis=2)
    np.testing.assert_allclose(distance, brute.min(axis=1), rtol=1e-12)
    np.testing.assert_allclose(brute[np.arange(len(queries)), index], brute.min(axis=1))


def test_different_counts_pair_each_reference_gaussian_with_its_nearest():
    scene = blob_scene(count=100)
    pruned = scene.subset(np.arange(0, 100, 2))
    errors, matching = attribute_errors(scene, pruned)
    assert matching.method == "nearest neighbour" and matching.unpicked_candidates == 0
    assert len(matching.index) == 100
