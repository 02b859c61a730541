"""Scene <-> attribute streams: what is coded, what is skipped, and the exact inverse."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.attribute_forms import canonical_rotations
from csgs_codec.attributes.streams import constant_channels, join_streams, split_streams
from csgs_codec.decisions.presets import PRESETS, preset
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply
from tests.conftest import SAMPLE, fixture


def test_zero_sh_bands_get_no_stream_and_decode_as_zeros():
    scene = read_ply(fixture("flat_tile_zero_sh.ply"))
    streams = split_streams(scene)
    assert not any(name.startswith("rest") for name in streams.float_streams)
    back = join_streams(streams, scene.positions)
    assert back.sh_rest.shape == scene.sh_rest.shape and not back.sh_rest.any()


def test_split_then_join_restores_every_attribute():
    scene = read_ply(fixture("sh3_iter7000.ply"))
    back = join_streams(split_streams(scene), scene.positions)
    np.testing.assert_array_equal(back.sh_dc, scene.sh_dc)
    np.testing.assert_array_equal(back.sh_rest, scene.sh_rest)
    np.testing.assert_array_equal(back.scales, scene.scales)
    np.testing.assert_array_equal(back.opacity, np.clip(scene.opacity, -10, 10))
    # The rotations in canonical form: the same Gaussians.
    assert np.abs(np.sum(back.rotations * canonical_rotations(scene.rotations), axis=1)
                  ).min() > 1 - 1e-6
    largest = np.exp(2 * scene.scales.max(axis=1))[:, None, None].astype(np.float64)
    np.testing.assert_allclose(_covariances(back.rotations, back.scales) / largest,
                               _covariances(scene.rotations, scene.scales) / largest, atol=1e-5)


def test_sh_bands_are_split_per_band():
    scene = read_ply(fixture("three_points_sh3.ply"))
    streams = split_streams(scene).float_streams
    assert streams["rest1"].shape == (3, 9)
    assert streams["rest2"].shape == (3, 15)
    assert streams["rest3"].shape == (3, 21)
    np.testing.assert_array_equal(streams["rest2"].reshape(3, 5, 3), scene.sh_rest[:, 3:8])


def test_constant_channels_are_found_in_coding_form():
    scene = read_ply(SAMPLE).subset(np.arange(100))
    scene.scales[:, 2] = -7.5
    found = constant_channels(split_streams(scene))
    assert any(c.stream == "scale" and c.channel == 2 and c.value == -7.5 for c in found)
    assert not any(c.stream == "dc" for c in found)


def test_presets_get_finer_with_quality():
    steps = [PRESETS[q].dc_step for q in range(1, 10)]
    assert steps == sorted(steps, reverse=True)
    bits = [PRESETS[q].position_bits for q in range(1, 10)]
    assert bits == sorted(bits)
    with pytest.raises(InputError):
        preset(0)


def _covariances(rotations: np.ndarray, log_scales: np.ndarray) -> np.ndarray:
    import torch

    from csgs_codec.render.projection import covariance_3d

    return covariance_3d(torch.as_tensor(log_scales, dtype=torch.float64),
                         torch.as_tensor(rotations, dtype=torch.float64)).numpy()


def test_canonical_rotations_keep_every_gaussian():
    rng = np.random.default_rng(5)
    rotations = rng.normal(size=(5000, 4)).astype(np.float32)
    log_scales = rng.normal(size=(5000, 3)).astype(np.float32)
    # Relative to each Gaussian's largest variance (float32 quaternions round there).
    largest = np.exp(2 * log_scales.max(axis=1))[:, None, None]
    canonical = canonical_rotations(rotations)
    assert np.all(np.argmax(np.abs(canonical), axis=1) == 0) and np.all(canonical[:, 0] > 0)
    np.testing.assert_allclose(_covariances(canonical, log_scales) / largest,
                               _covariances(rotations, log_scales) / largest, atol=1e-5)
    # A quaternion whose w is already the largest is kept (renormalised).
    np.testing.assert_allclose(canonical_rotations(canonical), canonical, atol=1e-6)
    assert canonical_rotations(np.zeros((0, 4), np.float32)).shape == (0, 4)


def test_the_axis_stream_of_a_split_scene_is_constant():
    scene = read_ply(fixture("sh3_iter7000.ply"))
    assert len(np.unique(np.argmax(np.abs(scene.rotations), axis=1))) > 1
    assert np.all(split_streams(scene).rot_axis == 0)
