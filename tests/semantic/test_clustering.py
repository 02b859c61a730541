"""Spherical k-means: recovers separated directions, is seeded, and rejects bad counts."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.semantic.clustering import MAX_CLUSTERS, spherical_kmeans, unit_rows


def three_directions(per: int = 200, seed: int = 0):
    rng = np.random.default_rng(seed)
    truth = np.repeat(np.arange(3), per)
    points = np.eye(4)[truth] + 0.05 * rng.standard_normal((3 * per, 4))
    return unit_rows(points)[0], truth


def test_kmeans_recovers_separated_directions():
    units, truth = three_directions()
    centroids, assignment = spherical_kmeans(units, 3)
    assert centroids.shape == (3, 4)
    np.testing.assert_allclose(np.linalg.norm(centroids, axis=1), 1.0)
    for label in range(3):  # each true group falls in exactly one cluster, and vice versa
        assert len(np.unique(assignment[truth == label])) == 1
    assert len(np.unique(assignment)) == 3


def test_kmeans_with_the_same_seed_gives_the_same_clusters():
    units, _ = three_directions(seed=4)
    a = spherical_kmeans(units, 7, seed=11)
    b = spherical_kmeans(units, 7, seed=11)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_kmeans_fits_a_sample_and_assigns_every_row():
    units, truth = three_directions(per=500)
    centroids, assignment = spherical_kmeans(units, 3, fit_sample=90)
    assert assignment.shape == truth.shape
    for label in range(3):
        assert len(np.unique(assignment[truth == label])) == 1


def test_kmeans_makes_at_most_one_cluster_per_row():
    units, _ = three_directions(per=1)
    centroids, assignment = spherical_kmeans(units, 10)
    assert len(centroids) == 3 and sorted(assignment) == [0, 1, 2]


@pytest.mark.parametrize("k", [0, -1, MAX_CLUSTERS + 1, 2.5])
def test_kmeans_rejects_bad_cluster_counts(k):
    units, _ = three_directions(per=5)
    with pytest.raises(InputError) as err:
        spherical_kmeans(units, k)
    assert err.value.property == "clusters"


def test_unit_rows_leave_zero_and_nonfinite_rows_invalid():
    units, valid = unit_rows(np.array([[3.0, 4.0], [0.0, 0.0], [np.inf, 1.0]]))
    np.testing.assert_allclose(units[0], [0.6, 0.8])
    assert valid.tolist() == [True, False, False]
    assert not units[1:].any()
