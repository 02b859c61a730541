"""Where stage 1's initial points come from: a PLY, the dataset, COLMAP, or random."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.train.initial_points import (
    find_initial_points,
    random_points,
    read_colmap_points,
    read_ply_points,
)
from tests.train.stage1_data import tiny_dataset


def _write_points_ply(path, points):
    header = ("ply\nformat ascii 1.0\n"
              f"element vertex {len(points)}\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n")
    path.write_text(header + "".join(f"{x} {y} {z}\n" for x, y, z in points))


def test_a_synthetic_dataset_starts_from_its_scene(tmp_path):
    data = tiny_dataset()
    data.write(tmp_path)
    points, source = find_initial_points(tmp_path, [v.camera for v in data.views])
    assert source.endswith("scene.ply")
    np.testing.assert_allclose(points, data.scene.positions, atol=1e-6)


def test_an_explicit_ply_wins(tmp_path):
    data = tiny_dataset()
    data.write(tmp_path)
    _write_points_ply(tmp_path / "cloud.ply", [(1, 2, 3), (4, 5, 6)])
    points, _ = find_initial_points(tmp_path, [], points=tmp_path / "cloud.ply")
    assert points.tolist() == [[1, 2, 3], [4, 5, 6]]


def test_nerfstudio_ply_file_path_is_followed(tmp_path):
    data = tiny_dataset()
    data.write(tmp_path)
    (tmp_path / "scene.ply").unlink()
    _write_points_ply(tmp_path / "sparse.ply", [(0, 0, 1)])
    document = json.loads((tmp_path / "transforms.json").read_text())
    document["ply_file_path"] = "sparse.ply"
    (tmp_path / "transforms.json").write_text(json.dumps(document))
    points, source = find_initial_points(tmp_path, [])
    assert points.tolist() == [[0, 0, 1]] and source.endswith("sparse.ply")


def test_colmap_points_text_and_binary_agree(tmp_path):
    expected = [[1.0, 2.0, 3.0], [-4.5, 0.25, 8.0]]
    text = tmp_path / "text"
    text.mkdir()
    (text / "points3D.txt").write_text(
        "# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]\n"
        "1 1 2 3 255 0 0 0.5 1 0 2 1\n2 -4.5 0.25 8 0 0 0 0.1\n")
    binary = tmp_path / "binary"
    binary.mkdir()
    record = struct.Struct("<Q3d3BdQ")
    payload = struct.pack("<Q", 2)
    payload += record.pack(1, 1, 2, 3, 255, 0, 0, 0.5, 2) + struct.pack("<iiii", 1, 0, 2, 1)
    payload += record.pack(2, -4.5, 0.25, 8, 0, 0, 0, 0.1, 0)
    (binary / "points3D.bin").write_bytes(payload)
    assert read_colmap_points(text).tolist() == expected
    assert read_colmap_points(binary).tolist() == expected


def test_malformed_point_files_are_refused_naming_them(tmp_path):
    (tmp_path / "points3D.bin").write_bytes(struct.pack("<Q", 10**9))
    with pytest.raises(InputError, match="points3D.bin"):
        read_colmap_points(tmp_path)
    (tmp_path / "points3D.bin").unlink()
    (tmp_path / "points3D.txt").write_text("1 1 nope 3\n")
    with pytest.raises(InputError, match="line 1"):
        read_colmap_points(tmp_path)
    (tmp_path / "bad.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\n"
                                      "property float x\nend_header\n1\n")
    with pytest.raises(InputError, match="'y'"):
        read_ply_points(tmp_path / "bad.ply")


def test_random_points_fill_the_ball_the_cameras_look_into():
    data = tiny_dataset()
    cameras = [v.camera for v in data.views]
    points = random_points(cameras, 2000, seed=1)
    np.testing.assert_array_equal(points, random_points(cameras, 2000, seed=1))
    centre = np.asarray(data.scene.positions, np.float64).mean(axis=0)
    distance = np.linalg.norm(cameras[0].position - centre)
    assert np.linalg.norm(points.mean(axis=0) - centre) < 0.2 * distance
