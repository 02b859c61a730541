"""Foreground masks: found in a capture's masks/ when they are 0/255, composited into the
training images, resized with them, a background-opacity term in stage 1, and the CLI."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.train.color_stage import initial_state, train_color_stage
from csgs_codec.train.datasets import find_foreground_masks, load_dataset
from csgs_codec.train.foreground import (
    background_alpha_loss,
    is_binary_mask,
    read_foreground_mask,
)
from csgs_codec.train.synthetic import make_synthetic_dataset
from csgs_codec.train.views import TrainingView
from tests.train.layouts import write_inria
from tests.train.stage1_data import tiny_color_settings, tiny_dataset

GREY = 0.6


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(7, objects=2, gaussians_per_object=60, views=4, width=40,
                                  height=30)


def with_grey_background(view: TrainingView) -> TrainingView:
    """The view's objects in front of a grey wall (a photo's background)."""
    image = view.image.copy()
    image[view.mask == 0] = GREY
    return TrainingView(image, view.camera, view.mask, name=view.name)


def write_capture(views, root, *, binary: bool = True):
    """INRIA layout with a grey background and masks/: 0/255 foreground (``binary``) or the
    instance ids."""
    write_inria([with_grey_background(v) for v in views], root)
    (root / "masks").mkdir()
    for i, view in enumerate(views):
        pixels = np.where(view.mask > 0, 255, 0) if binary else view.mask
        Image.fromarray(pixels.astype(np.uint8)).save(root / "masks" / f"view_{i:03d}.png")
    return root


def test_foreground_masks_read_half_grey_and_up_as_object(tmp_path):
    Image.fromarray(np.array([[0, 127, 128, 255]], np.uint8)).save(tmp_path / "m.png")
    np.testing.assert_array_equal(read_foreground_mask(tmp_path / "m.png"),
                                  [[False, False, True, True]])
    assert not is_binary_mask(tmp_path / "m.png")
    Image.fromarray(np.array([[0, 255]], np.uint8)).save(tmp_path / "b.png")
    assert is_binary_mask(tmp_path / "b.png")
    Image.fromarray(np.zeros((1, 2, 3), np.uint8)).save(tmp_path / "rgb.png")
    assert not is_binary_mask(tmp_path / "rgb.png")


def test_a_capture_masks_folder_of_0_255_images_is_found_as_foreground(tmp_path, synthetic):
    root = write_capture(synthetic.views, tmp_path / "binary")
    assert find_foreground_masks(root) == root / "masks"
    ids = write_capture(synthetic.views, tmp_path / "ids", binary=False)
    assert find_foreground_masks(ids) is None  # instance ids 0, 1, 2: not foreground
    (root / "masks" / "view_002.png").unlink()
    assert find_foreground_masks(root) is None  # a view without one: not foreground


def test_foreground_views_show_the_object_over_the_background_and_keep_no_instance_masks(
        tmp_path, synthetic):
    root = write_capture(synthetic.views, tmp_path)
    views = load_dataset(root, foreground=root / "masks", segment_missing=False,
                         background=(0.0, 0.0, 1.0))
    for view, truth in zip(views, synthetic.views):
        np.testing.assert_array_equal(view.foreground, truth.mask > 0)
        assert (view.image[~view.foreground] == [0.0, 0.0, 1.0]).all()
        assert np.abs(view.image[view.foreground] - truth.image[truth.mask > 0]).max() < 0.003
        assert view.mask is None  # masks/ held the foreground, not instance ids
    plain = load_dataset(root, segment_missing=False)
    assert plain[0].foreground is None and plain[0].mask is not None
    assert np.allclose(plain[0].image[synthetic.views[0].mask == 0], GREY, atol=0.003)


def test_foreground_masks_are_resized_with_the_images(tmp_path, synthetic):
    root = write_capture(synthetic.views, tmp_path)
    views = load_dataset(root, downscale=2.0, foreground=root / "masks", read_masks=False)
    truth = synthetic.views[1].mask > 0
    assert views[1].foreground.shape == (15, 20) == views[1].image.shape[:2]
    np.testing.assert_array_equal(views[1].foreground, truth[1::2, 1::2])


def test_a_foreground_mask_of_another_size_names_both_files_and_sizes(tmp_path, synthetic):
    root = write_capture(synthetic.views, tmp_path)
    Image.new("L", (20, 20)).save(root / "masks" / "view_001.png")
    with pytest.raises(InputError) as caught:
        load_dataset(root, foreground=root / "masks", read_masks=False)
    message = str(caught.value)
    assert "masks/view_001.png" in message and "images/view_001.png" in message
    assert "20x20" in message and "40x30" in message


def test_background_alpha_loss_is_the_mean_opacity_on_the_background():
    alpha = torch.tensor([[0.2, 0.4], [1.0, 0.0]], requires_grad=True)
    background = torch.tensor([[True, True], [False, False]])
    loss = background_alpha_loss(alpha, background)
    assert loss.item() == pytest.approx(0.3)
    loss.backward()
    np.testing.assert_allclose(alpha.grad.numpy(), [[0.5, 0.5], [0.0, 0.0]])
    assert background_alpha_loss(alpha, ~background | True).item() == pytest.approx(0.4)


def _background_opacity(weight: float) -> float:
    """Mean rendered opacity outside the objects after a short stage 1 on foreground views."""
    data = tiny_dataset()
    views = [TrainingView(v.image, v.camera, None, name=v.name, foreground=v.mask > 0)
             for v in data.views]
    settings = tiny_color_settings(iterations=60, background_alpha_weight=weight,
                                   rate_weight=0.0)
    state = initial_state(views, data.scene.positions, settings)
    train_color_stage(views, state)
    opacity = []
    with torch.no_grad():
        for view in views:
            out, _ = state.model.render(view.camera, None, settings.background)
            opacity.append(out.alpha.numpy()[~view.foreground].mean())
    return float(np.mean(opacity))


def test_the_background_opacity_term_makes_the_background_transparent():
    assert _background_opacity(2.0) < 0.7 * _background_opacity(0.0)


# --------------------------------------------------------------------------- command line
def _train(root, tmp_path, *extra):
    return main(["train", str(root), "-o", str(tmp_path / "out.csgs"), "--iterations", "4",
                 "--anchors", "30", "--features", "4", "--offsets", "2", "--no-semantic",
                 "--test-every", "0", "--points", str(tmp_path / "points.ply"), *extra])


@pytest.fixture
def capture(tmp_path, synthetic):
    from csgs_codec.interchange.ply_writer import write_ply

    write_ply(synthetic.scene, tmp_path / "points.ply")
    return write_capture(synthetic.views, tmp_path / "capture")


def test_train_says_when_it_found_foreground_masks_and_honours_the_off_switch(
        capture, tmp_path, capsys):
    assert _train(capture, tmp_path) == 0
    assert "foreground masks: " in capsys.readouterr().out
    assert _train(capture, tmp_path, "--no-foreground-masks") == 0
    assert "foreground masks" not in capsys.readouterr().out


@pytest.mark.parametrize("extra, fragment", [
    (["--foreground-masks", "nowhere"], "nowhere"),
    (["--foreground-masks", "M", "--no-foreground-masks"], "no-foreground-masks"),
    (["--resolution", "20"], "view_003.png"),
])
def test_bad_foreground_input_exits_2_with_one_line(capture, tmp_path, capsys, extra,
                                                    fragment):
    if extra[0] == "--resolution":  # a mask of another size, found after the same downscale
        Image.new("L", (30, 30)).save(capture / "masks" / "view_003.png")
        extra = ["--foreground-masks", str(capture / "masks"), *extra]
    assert _train(capture, tmp_path, *extra) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and fragment in err
    assert not (tmp_path / "out.csgs").exists()
