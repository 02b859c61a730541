"""Offset masks: the context coder round-trips, and masked offsets cost nothing."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.entropy.offset_masks import decode_masks, encode_masks
from csgs_codec.errors import FormatError
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.anchors.helpers import FAST_FIT, encoded, small_scene

EMPTY_RESIDUAL_STREAM = 2  # varint count 0, varint word count 0


@pytest.mark.parametrize("shape, p", [((500, 10), 0.8), ((37, 1), 0.5), ((200, 64), 0.1),
                                      ((0, 10), 0.5)])
def test_mask_stream_round_trips(shape, p):
    mask = np.random.default_rng(1).uniform(size=shape) < p
    assert np.array_equal(decode_masks(encode_masks(mask), *shape), mask)


def test_mask_stream_with_the_wrong_count_is_rejected():
    data = encode_masks(np.ones((10, 4), bool))
    with pytest.raises(FormatError):
        decode_masks(data, 11, 4)


def test_constant_masks_cost_almost_nothing():
    assert len(encode_masks(np.zeros((10000, 10), bool))) < 120
    assert len(encode_masks(np.ones((10000, 10), bool))) < 120


def test_masked_offset_values_change_no_byte():
    scene = small_scene()
    other = synthetic_anchor_scene(5, 60)
    noise = np.random.default_rng(7).uniform(-5, 5, other.offsets.shape).astype(np.float32)
    other.offsets = np.where(other.offset_mask[:, :, None], other.offsets, noise)
    assert not np.array_equal(other.offsets, scene.offsets)
    assert AnchorEncoder(5, fit=FAST_FIT).encode(other) == encoded().data


def test_all_masked_offsets_cost_zero_offset_bytes():
    none_masked = synthetic_anchor_scene(5, 60, masked_fraction=0.0)
    all_masked = synthetic_anchor_scene(5, 60, masked_fraction=0.0)
    all_masked.offset_mask[:] = False
    kept = AnchorEncoder(5, fit=FAST_FIT).encode_with_report(none_masked)
    dropped = AnchorEncoder(5, fit=FAST_FIT).encode_with_report(all_masked)
    assert dropped.chunk_bytes["AOFF"] == EMPTY_RESIDUAL_STREAM
    assert kept.chunk_bytes["AOFF"] > 20 * len(none_masked)
    assert len(kept.data) - len(dropped.data) >= kept.chunk_bytes["AOFF"] - 200
