"""Scene <-> attribute streams: what is coded, what is skipped, and the exact inverse."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.attribute_forms import normalize_quaternions
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
    dots = np.abs(np.sum(back.rotations * normalize_quaternions(scene.rotations), axis=1))
    assert dots.min() > 1 - 1e-6


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
