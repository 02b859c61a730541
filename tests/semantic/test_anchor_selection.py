"""Click selection on a Scaffold-GS anchor scene: the mask is over anchors, whose Gaussians
carry their anchor's semantic feature."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError, ModelError
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from csgs_codec.semantic import click_selection, select_at_click, selected_gaussians
from csgs_codec.semantic.evaluation import click_object_ious
from csgs_codec.semantic.synthetic import overview_camera
from tests.semantic.scenes import background_pixel, centre_pixel


@pytest.fixture(scope="module")
def anchors():
    scene = synthetic_anchor_scene(n_objects=5, anchors_per_object=150, seed=1)
    return scene, overview_camera(scene.positions)


def test_click_on_each_object_selects_its_anchors(anchors):
    scene, camera = anchors
    for mode in ("cosine", "cluster"):
        ious = click_object_ious(scene, camera, mode=mode)
        assert sorted(ious) == [0, 1, 2, 3, 4]
        assert min(ious.values()) >= 0.9, (mode, ious)


def test_anchor_mask_has_one_entry_per_anchor(anchors):
    scene, camera = anchors
    mask = select_at_click(scene, camera, *centre_pixel(scene, camera, 0))
    assert mask.shape == (len(scene),) and mask.dtype == np.bool_


def test_selected_gaussians_come_from_selected_anchors(anchors):
    scene, camera = anchors
    result = click_selection(scene, camera, *centre_pixel(scene, camera, 2))
    gaussians = selected_gaussians(scene, result.mask, camera)
    assert len(gaussians) > 0
    assert set(np.unique(gaussians.labels)) == {2}
    assert gaussians.semantic.shape == (len(gaussians), scene.semantic.shape[1])


def test_anchor_background_click_is_an_input_error(anchors):
    scene, camera = anchors
    with pytest.raises(InputError, match="nothing under the click"):
        select_at_click(scene, camera, *background_pixel(camera))


def test_anchor_scene_without_mlps_is_a_model_error(anchors):
    scene, camera = anchors
    bare = scene.subset(np.arange(len(scene)))
    bare.mlps = None
    with pytest.raises(ModelError):
        select_at_click(bare, camera, *centre_pixel(scene, camera, 0))


def test_selection_mask_of_the_wrong_shape_is_an_input_error(anchors):
    scene, camera = anchors
    with pytest.raises(InputError, match="selection mask"):
        selected_gaussians(scene, np.ones(3, bool), camera)
