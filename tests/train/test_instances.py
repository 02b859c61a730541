"""Instances lifted from stage-2 features and masks: one id per Gaussian, matching objects."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.train.instances import _visibility, approximate_neighbours, lift_instances
from csgs_codec.train.semantic_batch import ViewBatch
from csgs_codec.train.semantic_stage import prepare_semantic_views, train_semantic_features
from csgs_codec.train.synthetic import make_synthetic_dataset


@pytest.fixture(scope="module")
def trained():
    dataset = make_synthetic_dataset(7, objects=3, gaussians_per_object=60, views=4, width=48,
                                     height=36)
    views = prepare_semantic_views(dataset.scene, dataset.views)
    result = train_semantic_features(views, len(dataset.scene), iterations=80, seed=1)
    batch = ViewBatch.from_views([v.contributions for v in views], [v.mask for v in views],
                                 len(dataset.scene))
    return dataset, batch, result.features


def test_lifted_instances_match_the_objects(trained):
    dataset, batch, features = trained
    instances = lift_instances(batch, features, dataset.scene.positions, join_distance=2.0)
    labels = dataset.scene.labels
    objects = np.unique(labels)
    # Every object maps to one instance that holds nearly all of its Gaussians and little else.
    for label in objects:
        ids, counts = np.unique(instances.ids[labels == label], return_counts=True)
        main = ids[np.argmax(counts)]
        members = instances.ids == main
        iou = np.sum(members & (labels == label)) / np.sum(members | (labels == label))
        assert iou > 0.9, (label, iou)
    assert instances.ids.dtype == np.int32 and instances.ids.min() == 0
    assert instances.count == instances.ids.max() + 1
    assert np.array_equal(np.bincount(instances.ids), instances.counts)
    assert np.all(np.diff(instances.counts) <= 0)
    snapped = instances.features()
    assert snapped.shape == features.shape
    assert len(np.unique(snapped, axis=0)) == instances.count


def test_lifting_is_deterministic(trained):
    dataset, batch, features = trained
    first = lift_instances(batch, features, dataset.scene.positions, join_distance=2.0)
    again = lift_instances(batch, features, dataset.scene.positions, join_distance=2.0)
    assert np.array_equal(first.ids, again.ids)
    assert np.array_equal(first.prototypes, again.prototypes)


def test_bad_arguments_are_input_errors(trained):
    dataset, batch, features = trained
    with pytest.raises(InputError, match="features"):
        lift_instances(batch, features[:-1], dataset.scene.positions, join_distance=2.0)
    with pytest.raises(InputError, match="join distance"):
        lift_instances(batch, features, dataset.scene.positions, join_distance=0.0)
    with pytest.raises(InputError, match="neighbours"):
        lift_instances(batch, features, dataset.scene.positions, join_distance=2.0,
                       neighbours=0)


def test_approximate_neighbours_find_most_true_neighbours():
    points = np.random.default_rng(2).normal(size=(3000, 3))
    found = approximate_neighbours(points, 8)
    assert np.array_equal(found[:, 0], np.arange(len(points)))
    d2 = np.sum((points[:, None] - points[None]) ** 2, axis=2)
    exact = np.argsort(d2, axis=1)[:, :8]
    recall = np.mean([len(np.intersect1d(a, b)) / 8 for a, b in zip(found, exact)])
    assert recall > 0.95


def test_visibility_sums_each_groups_weights_as_its_coo_entries_give(trained):
    _, batch, _ = trained
    coo = batch.transpose.to_sparse_coo().coalesce()
    group = coo.indices()[0].numpy()
    weight = coo.values().double().numpy()
    groups = batch.transpose.shape[0]
    peak = np.zeros(groups)
    np.maximum.at(peak, group, weight)
    visibility, found_peak = _visibility(batch)
    assert np.array_equal(visibility, np.bincount(group, weights=weight, minlength=groups))
    assert np.array_equal(found_peak, peak)
