"""The built-in graph segmenter: separates colors, is deterministic, numbers ids in order."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.train import segmentation
from csgs_codec.train.segmentation import segment_image


def two_color_image(height: int = 48, width: int = 64) -> np.ndarray:
    image = np.zeros((height, width, 3), np.float32)
    image[:, : width // 2] = [0.9, 0.1, 0.1]
    image[:, width // 2:] = [0.1, 0.2, 0.9]
    return image


def test_two_color_image_gives_at_least_two_segments_split_at_the_border():
    ids = segment_image(two_color_image())
    assert len(np.unique(ids)) >= 2
    assert ids[:, :28].max() == ids[:, :28].min()  # the left half away from the border is one
    assert ids[:, 36:].max() == ids[:, 36:].min()
    assert ids[0, 0] != ids[0, -1]


def test_uniform_image_is_one_segment():
    np.testing.assert_array_equal(segment_image(np.full((20, 30, 3), 0.4, np.float32)), 0)


def test_ids_are_numbered_in_raster_order_of_first_pixel():
    ids = segment_image(two_color_image())
    first_seen = [int(i) for i in dict.fromkeys(ids.ravel().tolist())]
    assert first_seen == list(range(len(first_seen)))
    assert ids.dtype == np.int32


def test_segmentation_is_deterministic_and_matches_the_plain_python_loop(monkeypatch):
    rng = np.random.default_rng(1)
    image = np.clip(two_color_image(24, 32) + rng.normal(0, 0.05, (24, 32, 3)), 0, 1)
    compiled = segment_image(image)
    np.testing.assert_array_equal(segment_image(image), compiled)
    monkeypatch.setattr(segmentation, "_merge", segmentation._merge_components)
    np.testing.assert_array_equal(segment_image(image), compiled)


def test_large_images_are_segmented_at_reduced_size_with_full_size_ids(monkeypatch):
    monkeypatch.setattr(segmentation, "MAX_SEGMENT_PIXELS", 1000)
    ids = segment_image(two_color_image(80, 100))
    assert ids.shape == (80, 100)
    assert ids[0, 0] != ids[0, -1] and len(np.unique(ids)) >= 2


@pytest.mark.parametrize("image", [np.zeros((4, 4)), np.zeros((4, 4, 4)),
                                   np.full((4, 4, 3), np.nan)], ids=["grey", "rgba", "nan"])
def test_bad_images_are_rejected(image):
    with pytest.raises(InputError):
        segment_image(image)
