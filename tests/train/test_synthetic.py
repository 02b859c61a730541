"""Synthetic training scenes: determined by the seed, masks agree with the labelled Gaussians."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.render.rasterizer import render
from csgs_codec.train.synthetic import (
    BACKGROUND_ID,
    instance_mask,
    make_synthetic_dataset,
    synthetic_scene,
)

OPTIONS = {"objects": 3, "gaussians_per_object": 60, "views": 3, "width": 32, "height": 24}


@pytest.fixture(scope="module")
def dataset():
    return make_synthetic_dataset(5, **OPTIONS)


def test_same_seed_gives_identical_scene_images_masks_and_cameras(dataset):
    again = make_synthetic_dataset(5, **OPTIONS)
    assert again.scene.equals(dataset.scene)
    for a, b in zip(again.views, dataset.views):
        assert a.image.tobytes() == b.image.tobytes()
        assert a.mask.tobytes() == b.mask.tobytes()
        assert a.camera.world_to_camera.tobytes() == b.camera.world_to_camera.tobytes()


def test_other_seed_gives_another_scene(dataset):
    other = synthetic_scene(6, objects=3, gaussians_per_object=60)
    assert not other.equals(dataset.scene)


def test_scene_has_labels_one_to_k_with_equal_counts(dataset):
    labels = dataset.scene.labels
    assert labels.dtype == np.int32
    np.testing.assert_array_equal(np.bincount(labels), [0, 60, 60, 60])
    dataset.scene.validate()


def test_views_show_every_object_and_background(dataset):
    seen = set()
    for view in dataset.views:
        view.validate()
        seen |= set(np.unique(view.mask).tolist())
        assert view.image.min() >= 0 and view.image.max() <= 1
    assert seen == {BACKGROUND_ID, 1, 2, 3}


def test_background_pixels_are_where_the_render_is_mostly_transparent(dataset):
    view = dataset.views[0]
    alpha = render(dataset.scene, view.camera).alpha
    assert np.all(view.mask[alpha < 0.45] == BACKGROUND_ID)
    assert np.all(view.mask[alpha > 0.55] != BACKGROUND_ID)


def test_mask_id_is_the_object_whose_color_the_pixel_shows(dataset):
    scene = dataset.scene
    color = 0.5 + 0.28209479177387814 * scene.sh_dc
    object_colors = np.stack([color[scene.labels == k].mean(axis=0) for k in (1, 2, 3)])
    view = dataset.views[1]
    solid = render(scene, view.camera).alpha > 0.95
    nearest = np.argmin(np.linalg.norm(view.image[solid][:, None] / view.image[solid].max(
        axis=1, keepdims=True)[:, None] - object_colors / object_colors.max(
        axis=1, keepdims=True), axis=2), axis=1) + 1
    assert np.mean(nearest == view.mask[solid]) > 0.95


def test_instance_mask_needs_labels(dataset):
    unlabelled = dataset.scene.subset(np.arange(len(dataset.scene)))
    unlabelled.labels = None
    with pytest.raises(InputError, match="labels"):
        instance_mask(unlabelled, dataset.views[0].camera)
