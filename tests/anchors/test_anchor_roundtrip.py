"""Anchor scenes round-trip: decode == encoder reconstruction, documented error bounds."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.chunks.anchor_payloads import MLP_RELATIVE_STEP
from csgs_codec.codec.anchor_decoder import AnchorDecoder, is_anchor_file
from csgs_codec.decisions.presets import DEFAULT_QUALITY, MULTIPLIERS
from csgs_codec.entropy.anchor_attributes import FRAC_BITS
from csgs_codec.format import Chunk, read_layers, write_container
from tests.anchors.helpers import encoded, small_scene

#: Rounding of the float32 input onto the 2^-12 grid, plus float32 output rounding.
GRID_SLACK = 2.0 ** -(FRAC_BITS + 1) + 1e-6


@pytest.mark.parametrize("quality", [2, 8])
def test_decode_equals_encoder_reconstruction_bit_for_bit(quality):
    result = encoded(quality)
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    assert decoded.equals(result.reconstruction)
    assert decoded.features.tobytes() == result.reconstruction.features.tobytes()


@pytest.mark.parametrize("quality", [2, 8])
def test_attribute_errors_are_within_half_a_step(quality):
    result = encoded(quality)
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    original = small_scene().subset(result.order)
    m = len(original)
    for name, values, step in (
            ("features", original.features, result.steps["f"]),
            ("scaling", original.scaling, result.steps["scaling"]),
            ("semantic", original.semantic, result.steps["semantic"])):
        error = np.abs(getattr(decoded, name) - values).reshape(m, -1).max(axis=1)
        assert np.all(error <= step / 2 + GRID_SLACK), name
    mask = original.offset_mask
    error = np.abs(decoded.offsets - original.offsets).max(axis=2)
    assert np.all(error[mask] <= np.broadcast_to(result.steps["offsets"][:, None] / 2,
                                                 mask.shape)[mask] + GRID_SLACK)
    assert np.all(decoded.offsets[~mask] == 0)


def test_finer_quality_gives_smaller_steps_and_a_larger_file():
    coarse, fine = encoded(2), encoded(8)
    assert fine.steps["f"].mean() < coarse.steps["f"].mean()
    assert len(fine.data) > len(coarse.data)


def test_anchor_cells_round_trip_losslessly():
    result = encoded()
    decoded = AnchorDecoder().decode(result.data)
    original = small_scene().subset(result.order)
    assert np.abs(decoded.positions - original.positions).max() <= 1e-6
    assert np.array_equal(decoded.offset_mask, original.offset_mask)


def test_labels_and_semantic_names_round_trip():
    result = encoded()
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    original = small_scene().subset(result.order)
    assert np.array_equal(decoded.labels, original.labels)
    assert decoded.semantic_names == original.semantic_names


def test_mlp_weights_decode_as_the_encoder_reconstructs_them_within_half_a_step():
    result = encoded()
    decoded = AnchorDecoder().decode(result.data)
    original = small_scene().mlps
    for name, head in decoded.mlps.heads().items():
        for key, arr in head.arrays().items():
            assert np.array_equal(arr, result.reconstruction.mlps.heads()[name].arrays()[key])
            ref = original.heads()[name].arrays()[key]
            step = float(np.std(ref)) * MLP_RELATIVE_STEP * MULTIPLIERS[DEFAULT_QUALITY]
            # the coded step is the nearest on the 1/8-octave grid: up to 2^(1/16) larger
            assert np.abs(arr - ref).max() <= step * 0.53, (name, key)


def test_color_decode_equals_the_full_decode_without_semantics():
    data = encoded().data
    color = AnchorDecoder().decode(data, layers="color")
    full = AnchorDecoder().decode(data, layers="color,semantic")
    assert color.semantic is None and color.labels is None
    for name in ("positions", "features", "offsets", "scaling", "offset_mask"):
        assert getattr(color, name).tobytes() == getattr(full, name).tobytes(), name


def test_semantic_none_writes_no_semantic_layer():
    result = encoded(semantic="none")
    layers = {e.layer.label for e in read_layers(result.data, layers="base").toc}
    assert layers == {"base", "color"}
    assert len(result.data) < len(encoded().data)


def test_anchor_files_are_told_from_gaussian_files_by_their_header_chunk():
    assert is_anchor_file(encoded().data)
    gaussian = write_container([Chunk("SCNE", "base", b"header"), Chunk("GEOM", "base", b"")])
    assert not is_anchor_file(gaussian)
