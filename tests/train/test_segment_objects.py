"""Objects from the built-in segmenter's over-segments (csgs_codec/train/segment_objects.py):
pieces by 3D connectivity, merged where the views' segments agree, masks consistent across
views; and ``segment_scene`` without user masks."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.render.rasterizer import render
from csgs_codec.scene.orbit import orbit_cameras
from csgs_codec.train.segment import SegmentSettings, segment_scene
from csgs_codec.train.segment_objects import (
    BACKGROUND_ID,
    components,
    connected_pieces,
    object_masks,
)
from csgs_codec.train.segmentation import segment_image
from csgs_codec.train.semantic_stage import contribution_matrix
from csgs_codec.train.synthetic import SH_C0, synthetic_scene
from csgs_codec.train.views import TrainingView


def _two_tone_blobs():
    """Two shells apart, each half one colour and half another (the built-in segmenter
    splits each into two segments), labels 1 and 2."""
    scene = synthetic_scene(3, objects=2, gaussians_per_object=400)
    tones = {1: ((0.9, 0.1, 0.1), (0.1, 0.2, 0.9)), 2: ((0.1, 0.8, 0.2), (0.9, 0.9, 0.1))}
    colours = np.zeros((len(scene), 3))
    for label, (low, high) in tones.items():
        inside = scene.labels == label
        centre = np.median(scene.positions[inside, 2])
        upper = inside & (scene.positions[:, 2] > centre)
        colours[inside & ~upper] = low
        colours[upper] = high
    return dataclasses.replace(scene, sh_dc=((colours - 0.5) / SH_C0).astype(np.float32))


def _views(scene, *, masks: str):
    cameras = orbit_cameras(scene, 8, width=96, height=72, up="+z", elevation_deg=30.0)
    views = []
    for camera in cameras:
        image = np.clip(render(scene, camera).image, 0, 1).astype(np.float32)
        views.append(TrainingView(image, camera, segment_image(image), name=camera.name,
                                  oversegmented=masks == "builtin"))
    return views


@pytest.fixture(scope="module")
def blobs():
    scene = _two_tone_blobs()
    unlabelled = dataclasses.replace(scene, labels=None)
    return scene, unlabelled


def _object_ious(ids, labels):
    out = []
    for label in np.unique(labels):
        values, counts = np.unique(ids[labels == label], return_counts=True)
        members = ids == values[np.argmax(counts)]
        truth = labels == label
        out.append(np.sum(members & truth) / np.sum(members | truth))
    return out


def test_two_separated_blobs_are_two_instances_without_masks(blobs):
    scene, unlabelled = blobs
    views = _views(scene, masks="builtin")
    # The segmenter splits each blob: more segments than objects in every view.
    assert all(len(np.unique(view.mask)) > 3 for view in views)
    result = segment_scene(unlabelled, views, SegmentSettings(iterations=40))
    assert result.instances.count == 2
    assert min(_object_ious(result.instances.ids, scene.labels)) > 0.97


def test_segmenting_without_masks_is_deterministic(blobs):
    scene, unlabelled = blobs
    views = _views(scene, masks="builtin")
    first = segment_scene(unlabelled, views, SegmentSettings(iterations=20))
    again = segment_scene(unlabelled, views, SegmentSettings(iterations=20))
    assert np.array_equal(first.instances.ids, again.instances.ids)
    assert np.array_equal(first.scene.semantic, again.scene.semantic)


def test_over_segments_become_one_id_per_object_in_every_view(blobs):
    scene, _ = blobs
    views = _views(scene, masks="builtin")
    matrices = [contribution_matrix(scene, view.camera) for view in views]
    masks = object_masks(matrices, [view.mask for view in views], scene.positions)
    again = object_masks(matrices, [view.mask for view in views], scene.positions)
    assert all(np.array_equal(a, b) for a, b in zip(masks, again))
    truth_ids = {}
    for view, mask, matrix in zip(views, masks, matrices):
        assert mask.dtype == np.int32 and mask.shape == view.mask.shape
        coo = matrix.coalesce()
        pixel, group = (index.numpy() for index in coo.indices())
        # The object id each label's Gaussians draw most of their weight under.
        for label in (1, 2):
            mine = scene.labels[group] == label
            ids = mask.ravel()[pixel[mine]]
            weights = np.bincount(ids, weights=coo.values().numpy()[mine])
            truth_ids.setdefault(label, set()).add(int(np.argmax(weights)))
    # One id per object across all views, distinct objects distinct ids, none background.
    assert all(len(ids) == 1 for ids in truth_ids.values())
    assert truth_ids[1] != truth_ids[2]
    assert BACKGROUND_ID not in truth_ids[1] | truth_ids[2]


def test_pieces_split_at_gaps_and_floaters_stand_alone():
    rng = np.random.default_rng(0)
    left = rng.uniform(0, 1, (300, 3))
    right = rng.uniform(0, 1, (300, 3)) + [3.0, 0, 0]
    floater = np.array([[10.0, 10.0, 10.0]])
    pieces = connected_pieces(np.concatenate([left, right, floater]))
    assert len(np.unique(pieces[:300])) == 1 and len(np.unique(pieces[300:600])) == 1
    assert pieces[0] != pieces[300] and pieces[600] not in (pieces[0], pieces[300])
    assert pieces[0] == 0 and pieces[300] == 300  # named by their lowest member


def test_components_name_each_by_its_lowest_node():
    labels = components(7, np.array([4, 1, 6]), np.array([2, 4, 5]))
    assert labels.tolist() == [0, 1, 1, 3, 1, 5, 5]
    assert components(3, np.zeros(0, np.int64), np.zeros(0, np.int64)).tolist() == [0, 1, 2]


def _bar_views(count: int, pixels: int):
    """``count`` views of 1 x ``pixels`` images over G = 2 * pixels groups: groups 0..P-1 and
    P..2P-1 each drawn (weight 0.9) at the pixel of their index, in every view."""
    matrices = []
    for _ in range(count):
        pixel = np.concatenate([np.arange(pixels), np.arange(pixels)])
        group = np.arange(2 * pixels)
        weight = np.concatenate([np.full(pixels, 0.9), np.full(pixels, 0.05)])
        matrices.append(torch.sparse_coo_tensor(
            torch.as_tensor(np.stack([pixel, group])), torch.as_tensor(weight, dtype=torch.float32),
            (pixels, 2 * pixels)).coalesce())
    return matrices


def test_pieces_apart_in_3d_join_where_every_view_shows_them_as_one_segment():
    # Groups 0..19 on a line with a gap after 9: two pieces in 3D; one segment in every view.
    positions = np.zeros((40, 3))
    positions[:20, 0] = np.r_[np.arange(10), np.arange(10) + 50.0]
    positions[20:, 0] = 1000.0 + np.arange(20) * 0.01  # far, faint: background groups
    matrices = _bar_views(3, 20)
    segments = [np.zeros((1, 20), np.int32) for _ in matrices]
    masks = object_masks(matrices, segments, positions)
    assert all(np.all(mask == 1) for mask in masks)
    # Two segments, consistently: the pieces stay two objects.
    split = [np.repeat([[0, 1]], 10, axis=1).astype(np.int32) for _ in matrices]
    masks = object_masks(matrices, split, positions)
    assert all(len(np.unique(mask)) == 2 for mask in masks)
    assert all(np.array_equal(mask, masks[0]) for mask in masks)


def test_object_masks_refuse_mismatched_inputs(blobs):
    scene, _ = blobs
    camera = orbit_cameras(scene, 1, width=32, height=24)[0]
    matrix = contribution_matrix(scene, camera)
    with pytest.raises(InputError, match="segment images"):
        object_masks([matrix], [], scene.positions)
    with pytest.raises(InputError, match="do not match"):
        object_masks([matrix], [np.zeros((10, 10), np.int32)], scene.positions)
    with pytest.raises(InputError, match="positions"):
        object_masks([matrix], [np.zeros((24, 32), np.int32)], scene.positions[:, :2])
