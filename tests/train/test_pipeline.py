"""All three stages end to end: views -> .csgs, reproducible, resumable, and (slow) good."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.errors import InputError
from csgs_codec.train.evaluation import (
    click_miou,
    image_click_miou,
    nearest_labels,
    score_views,
    split_views,
)
from csgs_codec.train.pipeline import CHECKPOINT_FILE, train_scene
from csgs_codec.train.synthetic import make_synthetic_dataset
from tests.train.stage1_data import tiny_dataset, tiny_train_settings


@pytest.fixture(scope="module")
def result():
    data = tiny_dataset()
    return train_scene(data.views, data.scene.positions, tiny_train_settings())


def test_the_file_decodes_to_the_encoders_reconstruction(result):
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    assert decoded.equals(result.encode.reconstruction)
    assert decoded.semantic is not None and decoded.semantic.shape[1] == 6
    color_only = AnchorDecoder().decode(result.data, layers="color")
    assert color_only.semantic is None
    np.testing.assert_array_equal(color_only.features, decoded.features)


def test_the_stages_each_did_their_work(result):
    assert result.color_state.step == tiny_train_settings().color.iterations
    assert result.semantic is not None
    losses = result.semantic.losses
    assert losses[-1] < losses[0]
    assert set(result.seconds) == {"stage1", "color_encode", "stages2_3", "encode"}


def test_training_gives_the_same_bytes_twice(result):
    data = tiny_dataset()
    again = train_scene(data.views, data.scene.positions, tiny_train_settings())
    assert again.data == result.data


class _InterruptedError(Exception):
    pass


def test_an_interrupted_run_resumes_to_the_same_file(result, tmp_path):
    data = tiny_dataset()
    with pytest.raises(InputError, match="resume"):
        train_scene(data.views, data.scene.positions, tiny_train_settings(),
                    checkpoint_dir=tmp_path, resume=True)

    def interrupt(stage, progress):  # dies after the checkpoint at step 70
        if progress is not None and progress.step == 80:
            raise _InterruptedError

    with pytest.raises(_InterruptedError):
        train_scene(data.views, data.scene.positions, tiny_train_settings(),
                    checkpoint_dir=tmp_path, progress=interrupt)
    assert (tmp_path / CHECKPOINT_FILE).is_file()
    resumed = train_scene(data.views, data.scene.positions, tiny_train_settings(),
                          checkpoint_dir=tmp_path, resume=True)
    assert resumed.data == result.data


def test_views_without_masks_give_a_color_only_file():
    data = tiny_dataset()
    views = [type(v)(v.image, v.camera, None, v.name) for v in data.views]
    out = train_scene(views, data.scene.positions, tiny_train_settings(
        color={"iterations": 40}))
    assert out.semantic is None
    assert AnchorDecoder().decode(out.data, layers="color,semantic").semantic is None


@pytest.mark.slow
def test_three_rate_weights_train_three_smaller_files_that_still_segment():
    """Issue #9's end-to-end check: held-out PSNR, size falling with lambda, decoded mIoU."""
    data = make_synthetic_dataset(5, objects=4, gaussians_per_object=300, views=16,
                                  width=96, height=72)
    train, test = split_views(data.views, 4)
    sizes = []
    for weight in (0.001, 0.01, 0.05):
        settings = tiny_train_settings(
            color={"iterations": 600, "initial_anchors": 300, "feat_dim": 16, "n_offsets": 5,
                   "max_anchors": 1500, "growth_every": 100, "rate_weight": weight},
            semantic_iterations=150, stage3_iterations=100, encoder_fit=None)
        out = train_scene(train, data.scene.positions, settings)
        decoded = AnchorDecoder().decode(out.data, layers="color,semantic")
        scores = score_views(decoded, test)
        labels = nearest_labels(decoded.positions, data.scene.positions, data.scene.labels)
        assert scores.psnr > 28.0, (weight, scores)
        assert click_miou(decoded, labels, test) >= 0.9, weight
        assert image_click_miou(decoded, test) >= 0.9, weight
        sizes.append(sum(v for k, v in out.encode.chunk_bytes.items()
                         if k in ("AFEA", "AOFF", "ASCL")))
    assert sizes[0] > sizes[1] > sizes[2], sizes
