"""Clamping the infinite opacity logits that PlayCanvas's compressed PLY decodes to."""

from __future__ import annotations

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from benchmarks.peers.ply_fixup import OPACITY_LOGIT_LIMIT, clamp_infinite_opacity
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply


def _write_ply(path, opacity):
    names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1",
             "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    data = np.zeros(len(opacity), dtype=[(name, "<f4") for name in names])
    data["x"] = np.arange(len(opacity))
    data["rot_0"] = 1.0
    data["opacity"] = opacity
    PlyData([PlyElement.describe(data, "vertex")], text=False).write(str(path))


def test_infinite_opacity_is_clamped_and_counted(tmp_path):
    path = tmp_path / "decoded.ply"
    _write_ply(path, [np.inf, -np.inf, 0.5])
    assert clamp_infinite_opacity(path) == 2
    scene = read_ply(path)
    np.testing.assert_allclose(scene.opacity, [OPACITY_LOGIT_LIMIT, -OPACITY_LOGIT_LIMIT, 0.5],
                               rtol=1e-6)


def test_opacity_limit_is_one_millionth_from_the_ends():
    assert 1 / (1 + np.exp(-OPACITY_LOGIT_LIMIT)) == pytest.approx(1 - 1e-6, abs=1e-12)


def test_finite_file_is_left_byte_identical(tmp_path):
    path = tmp_path / "decoded.ply"
    _write_ply(path, [0.0, 2.0])
    before = path.read_bytes()
    assert clamp_infinite_opacity(path) == 0
    assert path.read_bytes() == before


def test_file_without_opacity_is_an_input_error(tmp_path):
    path = tmp_path / "not.ply"
    path.write_bytes(b"this is not a ply file")
    with pytest.raises(InputError):
        clamp_infinite_opacity(path)
