"""Dataset loaders: each camera layout reads back what was written; bad files are named."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from PIL import Image

from csgs_codec.errors import FallbackWarning, InputError
from csgs_codec.render.image_io import save_png
from csgs_codec.train.datasets import load_dataset
from csgs_codec.train.image_files import read_mask
from csgs_codec.train.synthetic import make_synthetic_dataset, write_transforms_dataset
from tests.train.layouts import write_colmap, write_inria

HALF_LEVEL = 0.5 / 255 + 1e-6


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(3, objects=3, gaussians_per_object=80, views=3, width=40,
                                  height=30)


def assert_same_cameras(loaded, original):
    for a, b in zip(loaded, original):
        assert (a.width, a.height) == (b.width, b.height)
        np.testing.assert_allclose([a.fx, a.fy, a.cx, a.cy], [b.fx, b.fy, b.cx, b.cy],
                                   rtol=1e-12)
        np.testing.assert_allclose(a.world_to_camera, b.world_to_camera, atol=1e-9)


def assert_same_views(loaded, original, *, masks=True):
    assert len(loaded) == len(original)
    assert_same_cameras([v.camera for v in loaded], [v.camera for v in original])
    for a, b in zip(loaded, original):
        assert a.image.dtype == np.float32 and a.image.shape == b.image.shape
        assert np.abs(a.image - b.image).max() <= HALF_LEVEL
        if masks:
            assert a.mask.dtype == np.int32
            np.testing.assert_array_equal(a.mask, b.mask)


def test_transforms_json_round_trip_keeps_images_masks_and_cameras(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    views = load_dataset(tmp_path)
    assert_same_views(views, synthetic.views)
    assert [v.name for v in views] == [v.name for v in synthetic.views]


def test_synthetic_dataset_writes_its_ground_truth_scene_with_labels(tmp_path, synthetic):
    from csgs_codec.interchange.ply_reader import read_ply

    target = synthetic.write(tmp_path)
    assert target == tmp_path / "transforms.json"
    scene = read_ply(tmp_path / "scene.ply")
    np.testing.assert_array_equal(scene.labels, synthetic.scene.labels)
    np.testing.assert_array_equal(scene.positions, synthetic.scene.positions)
    assert_same_views(load_dataset(tmp_path), synthetic.views)


def test_inria_cameras_json_folder_loads_images_and_masks(tmp_path, synthetic):
    write_inria(synthetic.views, tmp_path)
    masks = tmp_path / "masks"
    masks.mkdir()
    for i, view in enumerate(synthetic.views):
        Image.fromarray(view.mask.astype(np.uint8)).save(masks / f"view_{i:03d}.png")
    assert_same_views(load_dataset(tmp_path), synthetic.views)


@pytest.mark.parametrize("binary", [False, True], ids=["text", "binary"])
def test_colmap_model_folder_loads_images(tmp_path, synthetic, binary):
    write_colmap(synthetic.views, tmp_path, binary=binary)
    views = load_dataset(tmp_path, segment_missing=False)
    assert_same_views(views, synthetic.views, masks=False)
    assert all(v.mask is None for v in views)
    # The model folder itself finds the images two levels up.
    again = load_dataset(tmp_path / "sparse" / "0", segment_missing=False)
    assert_same_views(again, synthetic.views, masks=False)


def test_downscale_halves_images_masks_and_intrinsics(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    views = load_dataset(tmp_path, downscale=2)
    for small, full in zip(views, synthetic.views):
        assert small.image.shape == (15, 20, 3) and small.mask.shape == (15, 20)
        assert (small.camera.width, small.camera.height) == (20, 15)
        assert small.camera.fx == pytest.approx(full.camera.fx / 2)
        assert small.camera.cx == pytest.approx(full.camera.cx / 2)
        # Area averaging: each pixel is the mean of its 2x2 block of the stored image.
        stored = np.round(np.clip(full.image, 0, 1) * 255) / 255
        blocks = stored.reshape(15, 2, 20, 2, 3).mean(axis=(1, 3))
        np.testing.assert_allclose(small.image, blocks, atol=1e-5)
        np.testing.assert_array_equal(np.isin(small.mask, np.unique(full.mask)), True)


def test_missing_masks_fall_back_to_the_segmenter_with_a_warning(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    for mask_file in (tmp_path / "masks").iterdir():
        mask_file.unlink()
    (tmp_path / "masks").rmdir()
    with pytest.warns(FallbackWarning, match="built-in graph segmenter"):
        views = load_dataset(tmp_path)
    assert all(v.mask is not None and v.mask.dtype == np.int32 for v in views)
    assert all(len(np.unique(v.mask)) >= 2 for v in views)
    # Marked as over-segments: the semantic stages make them into objects first.
    assert all(v.oversegmented for v in views)


def test_segment_missing_false_leaves_masks_absent_without_warning(tmp_path, synthetic):
    write_inria(synthetic.views, tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        views = load_dataset(tmp_path, segment_missing=False)
    assert all(v.mask is None for v in views)


def test_missing_image_is_named(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    (tmp_path / "images" / "view_001.png").unlink()
    with pytest.raises(InputError, match="view_001") as info:
        load_dataset(tmp_path)
    assert "not found" in str(info.value)


def test_image_size_different_from_camera_is_named(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    save_png(np.zeros((10, 10, 3)), tmp_path / "images" / "view_002.png")
    with pytest.raises(InputError, match=r"view_002\.png.*10x10 but its camera is 40x30"):
        load_dataset(tmp_path)


def test_mask_size_different_from_image_is_named(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    Image.fromarray(np.zeros((5, 5), np.uint8)).save(tmp_path / "masks" / "view_000.png")
    with pytest.raises(InputError, match=r"masks/view_000\.png.*mask is 5x5"):
        load_dataset(tmp_path)


def test_missing_mask_file_is_named(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    (tmp_path / "masks" / "view_002.png").unlink()
    with pytest.raises(InputError, match=r"view_002\.png.*no mask"):
        load_dataset(tmp_path)


def test_unreadable_image_is_named(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    (tmp_path / "images" / "view_000.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match=r"view_000\.png.*cannot read image"):
        load_dataset(tmp_path)


def test_folder_without_cameras_is_named(tmp_path):
    with pytest.raises(InputError, match="no cameras found"):
        load_dataset(tmp_path)


def test_downscale_below_one_or_not_a_number_is_rejected(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    for bad in (0.5, float("nan"), float("inf"), "2", True):
        with pytest.raises(InputError, match="downscale"):
            load_dataset(tmp_path, downscale=bad)


def test_transparent_images_are_composited_over_the_background(tmp_path, synthetic):
    target = write_transforms_dataset(synthetic.views[:1], tmp_path)
    rgba = np.zeros((30, 40, 4), np.uint8)
    rgba[:, :20] = [255, 0, 0, 255]  # opaque red left half, transparent right half
    Image.fromarray(rgba).save(tmp_path / "images" / "view_000.png")
    (view,) = load_dataset(target, background=(1.0, 1.0, 1.0))
    np.testing.assert_array_equal(view.image[0, 0], [1, 0, 0])
    np.testing.assert_array_equal(view.image[0, -1], [1, 1, 1])


def test_rgb_and_sixteen_bit_masks_give_integer_ids(tmp_path):
    rgb = np.zeros((4, 5, 3), np.uint8)
    rgb[0, 0] = [1, 2, 3]
    Image.fromarray(rgb).save(tmp_path / "rgb.png")
    ids = read_mask(tmp_path / "rgb.png")
    assert ids[0, 0] == (1 << 16) + (2 << 8) + 3 and ids[1, 1] == 0
    wide = np.full((4, 5), 40000, np.uint16)
    Image.fromarray(wide).save(tmp_path / "wide.png")
    np.testing.assert_array_equal(read_mask(tmp_path / "wide.png"), 40000)


def test_transforms_file_path_without_suffix_finds_the_png(tmp_path, synthetic):
    target = write_transforms_dataset(synthetic.views[:2], tmp_path)
    document = json.loads(target.read_text())
    for frame in document["frames"]:
        frame["file_path"] = frame["file_path"].removesuffix(".png")
    target.write_text(json.dumps(document))
    assert_same_views(load_dataset(target), synthetic.views[:2])
