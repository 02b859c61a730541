"""Click selection: clicking an object's centre selects that object, from raw features and from
features decoded by the codec; bad clicks are InputErrors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import InputError
from csgs_codec.semantic import (
    DEFAULT_THRESHOLD,
    click_selection,
    render_feature_map,
    select_at_click,
)
from csgs_codec.semantic.evaluation import click_object_ious, mask_iou, mean_iou
from csgs_codec.semantic.synthetic import overview_camera, semantic_directions
from tests.semantic.scenes import (
    OBJECTS,
    background_pixel,
    centre_pixel,
    five_objects,
    label_mask,
)


@pytest.fixture(scope="module")
def objects():
    return five_objects()


@pytest.fixture(scope="module")
def decoded(objects):
    scene, camera = objects
    report = Encoder(quality=5).encode_with_report(scene)
    decoded = Decoder().decode(report.data, layers="color,semantic")
    return decoded, scene.labels[report.order], camera


def test_default_threshold_is_documented_value():
    assert DEFAULT_THRESHOLD == 0.9


def test_click_on_each_object_selects_it_from_raw_features(objects):
    scene, camera = objects
    for label in range(OBJECTS):
        mask = select_at_click(scene, camera, *centre_pixel(scene, camera, label))
        assert mask.shape == (len(scene),) and mask.dtype == np.bool_
        assert mask_iou(mask, label_mask(scene.labels, label)) >= 0.9, label


def test_click_on_each_object_selects_it_from_decoded_features(decoded):
    scene, labels, camera = decoded
    assert scene.semantic is not None and scene.semantic.shape[1] == 6
    ious = click_object_ious(scene, camera, labels)
    assert sorted(ious) == list(range(OBJECTS))
    assert min(ious.values()) >= 0.9, ious


def test_cluster_mode_selects_each_object(objects):
    scene, camera = objects
    ious = click_object_ious(scene, camera, mode="cluster")
    assert min(ious.values()) >= 0.9, ious


def test_cluster_mode_is_deterministic(objects):
    scene, camera = objects
    x, y = centre_pixel(scene, camera, 2)
    first = click_selection(scene, camera, x, y, mode="cluster", clusters=12)
    second = click_selection(scene, camera, x, y, mode="cluster", clusters=12)
    assert first.clusters is not None
    np.testing.assert_array_equal(first.clusters, second.clusters)
    np.testing.assert_array_equal(first.mask, second.mask)


def test_cluster_mode_merges_clusters_that_split_one_object(objects):
    scene, camera = objects
    x, y = centre_pixel(scene, camera, 1)
    result = click_selection(scene, camera, x, y, mode="cluster", clusters=15)
    assert len(np.unique(result.clusters[result.mask])) > 1  # the object was split ...
    assert mask_iou(result.mask, label_mask(scene.labels, 1)) >= 0.9  # ... and merged back


def test_clicked_feature_is_the_objects_unit_direction(objects):
    scene, camera = objects
    result = click_selection(scene, camera, *centre_pixel(scene, camera, 3))
    assert math.isclose(float(np.linalg.norm(result.clicked_feature)), 1.0, rel_tol=1e-5)
    direction = scene.semantic[scene.labels == 3].mean(axis=0)
    assert float(result.clicked_feature @ direction / np.linalg.norm(direction)) > 0.99
    assert 0.05 <= result.alpha < 1.0


def test_scores_are_cosines_and_mask_is_scores_over_threshold(objects):
    scene, camera = objects
    result = click_selection(scene, camera, *centre_pixel(scene, camera, 0), threshold=0.5,
                             mode="cosine")
    units = scene.semantic / np.linalg.norm(scene.semantic, axis=1, keepdims=True)
    np.testing.assert_allclose(result.scores, units @ result.clicked_feature, atol=1e-5)
    np.testing.assert_array_equal(result.mask, result.scores >= 0.5)


def test_lower_threshold_selects_a_superset(objects):
    scene, camera = objects
    x, y = centre_pixel(scene, camera, 4)
    strict = select_at_click(scene, camera, x, y, threshold=0.99, mode="cosine")
    loose = select_at_click(scene, camera, x, y, threshold=0.5, mode="cosine")
    everything = select_at_click(scene, camera, x, y, threshold=-1.0, mode="cosine")
    assert strict.sum() < loose.sum() and not np.any(strict & ~loose)
    assert everything.all()


def test_zero_features_are_never_selected(objects):
    scene, camera = objects
    scene = scene.subset(np.arange(len(scene)))
    zeroed = np.flatnonzero(scene.labels == 2)[:50]
    scene.semantic[zeroed] = 0.0
    for mode, threshold in (("cosine", 0.9), ("cosine", -1.0), ("cluster", 0.9)):
        result = click_selection(scene, camera, *centre_pixel(scene, camera, 2), mode=mode,
                                 threshold=threshold)
        assert not result.mask[zeroed].any()
        assert result.mask[scene.labels == 2].sum() >= 350


@pytest.mark.parametrize("x, y", [(-1, 10), (10, -0.5), (320, 10), (10, 240),
                                  (float("nan"), 10), (10, float("inf"))])
def test_click_outside_the_image_is_an_input_error(objects, x, y):
    scene, camera = objects
    with pytest.raises(InputError, match="outside the 320x240 image") as err:
        select_at_click(scene, camera, x, y)
    assert err.value.property == "click"


def test_click_on_the_background_is_an_input_error(objects):
    scene, camera = objects
    with pytest.raises(InputError, match="nothing under the click") as err:
        select_at_click(scene, camera, *background_pixel(camera))
    assert err.value.property == "click"


def test_scene_without_semantic_features_is_an_input_error(objects):
    scene, camera = objects
    bare = scene.subset(np.arange(len(scene)))
    bare.semantic, bare.semantic_names = None, ()
    with pytest.raises(InputError, match="no semantic features") as err:
        select_at_click(bare, camera, *centre_pixel(scene, camera, 0), mode="cosine")
    assert err.value.property == "semantic"
    bare.labels = None  # instance mode reads labels too; with neither there is nothing
    with pytest.raises(InputError, match="no labels or semantic features") as err:
        select_at_click(bare, camera, *centre_pixel(scene, camera, 0))
    assert err.value.property == "semantic"


@pytest.mark.parametrize("options, prop", [
    ({"threshold": 1.5}, "threshold"), ({"threshold": float("nan")}, "threshold"),
    ({"threshold": True}, "threshold"), ({"mode": "nearest"}, "mode"),
    ({"mode": "cluster", "clusters": 0}, "clusters"),
    ({"mode": "cluster", "clusters": 10_000}, "clusters")])
def test_bad_selection_options_are_input_errors(objects, options, prop):
    scene, camera = objects
    with pytest.raises(InputError) as err:
        click_selection(scene, camera, *centre_pixel(scene, camera, 0), **options)
    assert err.value.property == prop


def test_mask_iou_is_intersection_over_union():
    a = np.array([True, True, False, False])
    b = np.array([True, False, True, False])
    assert mask_iou(a, b) == pytest.approx(1 / 3)
    assert mask_iou(a, a) == 1.0 and mask_iou(~a & a, ~a & a) == 1.0
    assert mean_iou({0: 1.0, 1: 0.5}) == 0.75 and mean_iou({}) == 0.0


def test_semantic_directions_are_orthonormal_when_they_fit():
    directions = semantic_directions(5, 6, np.random.default_rng(0))
    np.testing.assert_allclose(directions @ directions.T, np.eye(5), atol=1e-12)


def test_one_feature_map_serves_many_clicks(objects):
    scene, camera = objects
    feature_map = render_feature_map(scene, camera)
    assert feature_map.features.shape == (camera.height, camera.width, 6)
    for label in (0, 4):
        x, y = centre_pixel(scene, camera, label)
        reused = click_selection(scene, camera, x, y, feature_map=feature_map)
        fresh = click_selection(scene, camera, x, y)
        np.testing.assert_array_equal(reused.mask, fresh.mask)


def test_feature_map_of_another_camera_is_an_input_error(objects):
    scene, camera = objects
    feature_map = render_feature_map(scene, overview_camera(scene.positions, width=64,
                                                            height=48))
    with pytest.raises(InputError, match="another camera") as err:
        click_selection(scene, camera, 10, 10, feature_map=feature_map, mode="cosine")
    assert err.value.property == "feature_map"


def test_empty_view_has_nothing_under_any_click(objects):
    scene, camera = objects
    empty = scene.subset(np.zeros(len(scene), bool))
    with pytest.raises(InputError, match="nothing under the click"):
        select_at_click(empty, camera, 160, 120)


def test_instance_mode_selects_labels_directly(objects):
    import dataclasses

    scene, camera = objects
    bare = dataclasses.replace(scene, semantic=None, semantic_names=())
    for label in range(OBJECTS):
        result = click_selection(bare, camera, *centre_pixel(scene, camera, label),
                                 mode="instance")
        assert result.instance_source == "labels"
        assert np.array_equal(result.mask, bare.labels == bare.labels[result.mask][0])
        assert mask_iou(result.mask, label_mask(scene.labels, label)) == 1.0, label
        assert result.clicked_feature.shape == (0,)


def test_instance_mode_reads_distinct_features_as_instances(objects):
    import dataclasses

    scene, camera = objects
    prototypes = np.random.default_rng(1).normal(size=(int(scene.labels.max()) + 1, 6))
    snapped = dataclasses.replace(scene, labels=None,
                                  semantic=prototypes[scene.labels].astype(np.float32))
    for label in range(OBJECTS):
        result = click_selection(snapped, camera, *centre_pixel(scene, camera, label),
                                 mode="instance")
        assert result.instance_source == "features"
        assert mask_iou(result.mask, label_mask(scene.labels, label)) == 1.0, label


def test_instance_mode_on_continuous_features_follows_the_cosine_rule(objects):
    import dataclasses

    scene, camera = objects
    continuous = dataclasses.replace(scene, labels=None)
    x, y = centre_pixel(scene, camera, 0)
    result = click_selection(continuous, camera, x, y, mode="instance")
    cosine = click_selection(continuous, camera, x, y, mode="cosine")
    assert result.mode == "cosine" and result.instance_source is None
    assert np.array_equal(result.mask, cosine.mask)
    assert mask_iou(result.mask, label_mask(scene.labels, 0)) >= 0.9


def test_instance_mode_on_the_background_is_an_input_error(objects):
    scene, camera = objects
    with pytest.raises(InputError, match="nothing under the click"):
        click_selection(scene, camera, *background_pixel(camera), mode="instance")
