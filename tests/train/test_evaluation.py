"""Scoring trained scenes: held-out views, label transfer, 2D and per-anchor click mIoU."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.train.evaluation import (
    image_click_iou,
    interior_pixel,
    nearest_labels,
    split_views,
)
from tests.train.stage1_data import tiny_dataset


def test_interior_pixel_is_deep_inside_the_mask():
    mask = np.zeros((20, 30), bool)
    mask[2:18, 5:12] = True
    mask[2:4, 12:29] = True  # a thin arm: clicks should avoid it
    x, y = interior_pixel(mask)
    assert 7 <= x <= 9 and 8 <= y <= 11
    with pytest.raises(InputError):
        interior_pixel(np.zeros((4, 4), bool))


def test_every_kth_view_is_held_out():
    views = list(range(9))
    train, test = split_views(views, 4)
    assert test == [0, 4, 8] and train == [1, 2, 3, 5, 6, 7]
    assert split_views(views, 0) == (views, [])
    assert split_views([1], 4) == ([1], [])


def test_nearest_labels_carry_ground_truth_over():
    reference = np.array([[0, 0, 0], [10, 0, 0]], np.float64)
    labels = nearest_labels(np.array([[1, 0, 0], [9, 1, 0], [4.9, 0, 0]]), reference,
                            np.array([3, 7]))
    assert labels.tolist() == [3, 7, 3]


def test_perfect_features_give_image_ious_near_one():
    """Anchors carrying one-hot features of their true object select each object cleanly."""
    from csgs_codec.model.anchor_hyperprior import FitSettings
    from csgs_codec.train.pipeline import train_scene
    from tests.train.stage1_data import tiny_train_settings

    data = tiny_dataset()
    result = train_scene(data.views, data.scene.positions,
                         tiny_train_settings(encoder_fit=FitSettings(steps=20, batch=128)))
    scene = result.encode.reconstruction
    labels = nearest_labels(scene.positions, data.scene.positions, data.scene.labels)
    scene.semantic = np.eye(6, dtype=np.float32)[labels - 1]
    ious = image_click_iou(scene, data.views[1])
    assert len(ious) == 3 and min(ious.values()) > 0.8
    scene.semantic = np.ones_like(scene.semantic)  # one feature for all: selects everything
    assert min(image_click_iou(scene, data.views[1]).values()) < 0.6
