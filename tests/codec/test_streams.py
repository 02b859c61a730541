"""Scene <-> attribute streams: what is coded, what is skipped, and the exact inverse."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.attribute_forms import (
    SORTED_LARGEST_MIN,
    canonical_orientations,
    canonical_rotations,
)
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
    np.testing.assert_array_equal(back.scales, scene.scales)
    assert np.abs(np.sum(back.rotations * canonical_rotations(scene.rotations), axis=1)
                  ).min() > 1 - 1e-6
    back = join_streams(split_streams(scene, sort_axes=True), scene.positions)
    np.testing.assert_array_equal(back.sh_dc, scene.sh_dc)
    np.testing.assert_array_equal(back.sh_rest, scene.sh_rest)
    np.testing.assert_array_equal(back.opacity, np.clip(scene.opacity, -10, 10))
    # The same Gaussians with their axes in the canonical order.
    rotations, scales = canonical_orientations(scene.rotations, scene.scales)
    np.testing.assert_array_equal(back.scales, scales)
    ordered = np.all(np.diff(back.scales, axis=1) <= 0, axis=1)
    assert ordered.mean() > 0.9  # all but those the guard keeps (canonical_orientations)
    assert np.abs(np.sum(back.rotations * rotations, axis=1)).min() > 1 - 1e-6
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
    # The coding form sorts each Gaussian's scales, largest first where the guard lets it:
    # the smallest of all lands in channel 2 (or stays there).
    scene.scales[:, 2] = -12.5
    assert scene.scales[:, :2].min() > -12.5
    found = constant_channels(split_streams(scene, sort_axes=True))
    assert any(c.stream == "scale" and c.channel == 2 and c.value == -12.5 for c in found)
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


def test_canonical_forms_keep_every_gaussian():
    rng = np.random.default_rng(5)
    rotations = rng.normal(size=(5000, 4)).astype(np.float32)
    log_scales = rng.normal(size=(5000, 3)).astype(np.float32)
    log_scales[:50, 1] = log_scales[:50, 0]  # ties keep their order
    # Relative to each Gaussian's largest variance (float32 quaternions round there).
    largest = np.exp(2 * log_scales.max(axis=1))[:, None, None]
    reference = _covariances(rotations, log_scales) / largest
    canonical = canonical_rotations(rotations)
    assert np.all(np.argmax(np.abs(canonical), axis=1) == 0)
    np.testing.assert_allclose(_covariances(canonical, log_scales) / largest, reference,
                               atol=1e-5)
    # A quaternion whose w is already the largest is kept (renormalised).
    np.testing.assert_allclose(canonical_rotations(canonical), canonical, atol=1e-6)
    for guard in (0.0, SORTED_LARGEST_MIN, 1.0):
        turned, sorted_scales = canonical_orientations(rotations, log_scales, guard)
        ordered = np.all(np.diff(sorted_scales, axis=1) <= 0, axis=1)
        # The guard keeps a Gaussian's axes where sorting would lower its rotation's largest
        # component below the guard and below its own; it sorts every other one.
        unsorted = canonical_orientations(rotations[~ordered], log_scales[~ordered], 0.0)[0]
        assert np.all(unsorted[:, 0] < np.minimum(canonical[~ordered, 0], guard))
        np.testing.assert_array_equal(turned[~ordered], canonical[~ordered])
        assert np.all(ordered) == (guard == 0.0)
        assert np.all(np.argmax(np.abs(turned), axis=1) == 0)
        np.testing.assert_allclose(_covariances(turned, sorted_scales) / largest, reference,
                                   atol=1e-5)
    # The identity stays where a cyclic relabelling would take it to (1/2, 1/2, 1/2, 1/2).
    identity = np.array([[1.0, 0.0, 0.0, 0.0]], np.float32)
    cyclic = np.array([[-3.0, -1.0, -2.0]], np.float32)
    assert np.allclose(canonical_orientations(identity, cyclic, 0.0)[0], 0.5, atol=1e-6)
    kept = canonical_orientations(identity, cyclic)
    np.testing.assert_array_equal(kept[0], identity)
    np.testing.assert_array_equal(kept[1], cyclic)
    empty = canonical_orientations(np.zeros((0, 4), np.float32), np.zeros((0, 3), np.float32))
    assert empty[0].shape == (0, 4) and empty[1].shape == (0, 3)


def test_the_axis_stream_of_a_split_scene_is_constant():
    scene = read_ply(fixture("sh3_iter7000.ply"))
    assert len(np.unique(np.argmax(np.abs(scene.rotations), axis=1))) > 1
    assert np.all(split_streams(scene).rot_axis == 0)
    streams = split_streams(scene, sort_axes=True)
    assert np.all(streams.rot_axis == 0)
    assert np.mean(np.all(np.diff(streams.float_streams["scale"], axis=1) <= 0, axis=1)) > 0.9
