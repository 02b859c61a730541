"""The writers (.splat, SPZ v3/v4, GLB): values read back within each format's precision,
the same quantization as the format's own tools, and the choice of format by extension."""

from __future__ import annotations

import json
import struct
import warnings

import numpy as np
import pytest

from csgs_codec.codec.files import read_scene_with_report
from csgs_codec.errors import DataLossWarning, InputError, UnsupportedError
from csgs_codec.interchange import write_scene
from csgs_codec.interchange.gltf import glb_bytes, parse_glb
from csgs_codec.interchange.splat import RECORD, parse_splat, splat_bytes
from csgs_codec.interchange.spz import parse_spz, spz_bytes
from tests.interchange.helpers import DATA, alphas, colors, rotation_error

SH_C0 = 0.28209479177387814


@pytest.fixture(scope="module")
def brush():
    """200 real Gaussians with SH degree 3 (Brush output, CC0)."""
    return read_scene_with_report(DATA / "brush_sh3.ply")[0]


def test_splat_round_trip_keeps_values_within_one_8_bit_step(brush):
    scene, source = parse_splat(splat_bytes(brush))
    assert (source.format, len(scene), scene.sh_degree_stored) == ("splat", 200, 0)
    np.testing.assert_array_equal(scene.positions, brush.positions)
    np.testing.assert_allclose(scene.scales, brush.scales, atol=1e-6)
    assert np.abs(colors(scene) - np.clip(colors(brush), 0, 1)).max() <= 0.5 / 255 + 1e-9
    assert np.abs(alphas(scene) - alphas(brush)).max() <= 0.5 / 255 + 1e-9
    assert rotation_error(scene.rotations, brush.rotations).max() < 1e-4


def test_splat_records_equal_antimatter15s_converter_up_to_its_truncation(brush):
    """brush_sh3.splat was written by antimatter15's convert.py (sorted by size and
    opacity, color and rotation truncated where csgs rounds)."""
    theirs = np.frombuffer((DATA / "brush_sh3.splat").read_bytes(), RECORD)
    ours = np.frombuffer(splat_bytes(brush), RECORD)
    order = [int(np.flatnonzero((ours["position"] == p).all(axis=1))[0])
             for p in theirs["position"]]
    ours = ours[order]
    np.testing.assert_allclose(ours["scale"], theirs["scale"], rtol=1e-6)
    for field in ("rgba", "rotation"):
        diff = ours[field].astype(int) - theirs[field].astype(int)
        assert diff.min() >= 0 and diff.max() <= 1, field  # round vs truncate: 0 or +1


@pytest.mark.parametrize("version", [3, 4])
def test_spz_round_trip_within_spz_precision(brush, version):
    data = spz_bytes(brush, version=version)
    assert data == spz_bytes(brush, version=version)  # deterministic bytes
    scene, source = parse_spz(data)
    assert (source.version, len(scene), scene.sh_degree_stored) == (str(version), 200, 3)
    assert source.details["fractional_bits"] == 12
    assert np.abs(scene.positions - brush.positions).max() <= 2 ** -13 + 1e-6
    reach = 127.5 / (0.15 * 255) * SH_C0
    want = np.clip(colors(brush), 0.5 - reach, 0.5 + reach)
    assert np.abs(colors(scene) - want).max() <= 0.5 / (0.15 * 255) * SH_C0 + 1e-6
    assert np.abs(alphas(scene) - alphas(brush)).max() <= 0.5 / 255 + 1e-6
    assert np.abs(scene.scales - np.clip(brush.scales, -10, 5.9375)).max() <= 1 / 32 + 1e-6
    assert rotation_error(scene.rotations, brush.rotations).max() < 1e-5
    assert np.abs(scene.sh_rest - np.clip(brush.sh_rest, -1, 127 / 128)).max() <= 8.5 / 128


@pytest.mark.parametrize("version", [3, 4])
def test_spz_quantizes_exactly_as_niantics_library(brush, version):
    """brush_sh3.v3/v4.spz were written by Niantic's spz library (WebAssembly, through
    splat-transform) from the same PLY: the decoded attributes are identical."""
    ours = parse_spz(spz_bytes(brush, version=version))[0]
    theirs = parse_spz((DATA / f"brush_sh3.v{version}.spz").read_bytes())[0]
    for key in ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations"):
        np.testing.assert_array_equal(getattr(ours, key), getattr(theirs, key), err_msg=key)


def test_spz_keeps_far_positions_by_spending_fewer_fractional_bits(brush):
    far = brush.subset(np.arange(len(brush)))
    far.positions = (far.positions * 400).astype(np.float32)  # up to ~7,200 units
    scene, source = parse_spz(spz_bytes(far))
    bits = source.details["fractional_bits"]
    assert bits == 10
    assert np.abs(scene.positions - far.positions).max() <= 2.0 ** -(bits + 1) + 1e-3
    far.positions[0, 0] = 9e6
    with pytest.raises(InputError, match="24-bit range"):
        spz_bytes(far)


def _glb_accessors(data: bytes) -> dict[str, np.ndarray]:
    """name -> values of every float attribute of the first primitive, parsed here with
    struct and numpy only (not with the reader under test)."""
    json_length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + json_length])
    blob = data[20 + json_length + 8:]
    out = {}
    for name, index in doc["meshes"][0]["primitives"][0]["attributes"].items():
        accessor = doc["accessors"][index]
        if accessor["componentType"] != 5126:
            continue
        view = doc["bufferViews"][accessor["bufferView"]]
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[accessor["type"]]
        out[name] = np.frombuffer(blob, "<f4", count=accessor["count"] * width,
                                  offset=view["byteOffset"] + accessor.get("byteOffset", 0)
                                  ).reshape(-1, width)
    return out


def test_glb_attributes_equal_splat_transforms_glb_of_the_same_scene(brush):
    """brush_sh3.glb was written by splat-transform 3.7.0 from brush_sh3.ply: the same
    axes, quaternion order, linear scales, opacities and SH coefficient layout."""
    ours, theirs = _glb_accessors(glb_bytes(brush)), _glb_accessors(
        (DATA / "brush_sh3.glb").read_bytes())
    assert sorted(ours) == sorted(theirs) and len(ours) == 5 + 15
    for name in theirs:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=2e-6, atol=1e-7,
                                   err_msg=name)


def test_glb_structure_follows_the_extension(brush):
    data = glb_bytes(brush)
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, kind = struct.unpack_from("<II", data, 12)
    assert kind == 0x4E4F534A and json_length % 4 == 0
    doc = json.loads(data[20:20 + json_length])
    primitive = doc["meshes"][0]["primitives"][0]
    assert primitive["mode"] == 0 and doc["extensionsUsed"] == ["KHR_gaussian_splatting"]
    extension = primitive["extensions"]["KHR_gaussian_splatting"]
    assert extension["kernel"] == "ellipse"
    assert extension["colorSpace"] == "srgb_rec709_display"
    position = doc["accessors"][primitive["attributes"]["POSITION"]]
    values = _glb_accessors(data)["POSITION"]
    assert position["min"] == values.min(axis=0).tolist()
    assert position["max"] == values.max(axis=0).tolist()
    rotation = _glb_accessors(data)["KHR_gaussian_splatting:ROTATION"]
    np.testing.assert_allclose(np.linalg.norm(rotation, axis=1), 1.0, atol=1e-6)
    opacity = _glb_accessors(data)["KHR_gaussian_splatting:OPACITY"]
    assert opacity.min() >= 0 and opacity.max() <= 1
    for view in doc["bufferViews"]:
        assert view["byteOffset"] % 4 == 0


def test_glb_round_trip_through_the_reader(brush):
    scene, _ = parse_glb(glb_bytes(brush))
    np.testing.assert_array_equal(scene.positions, brush.positions)
    np.testing.assert_array_equal(scene.sh_rest, brush.sh_rest)
    np.testing.assert_allclose(scene.rotations, brush.rotations
                               / np.linalg.norm(brush.rotations, axis=1, keepdims=True),
                               atol=3e-7)
    np.testing.assert_allclose(alphas(scene), alphas(brush), atol=1e-7)


def test_glb_points_load_in_trimesh(brush):
    """trimesh, an independent glTF reader, sees the points (a viewer without the
    extension shows them as a point cloud)."""
    trimesh = pytest.importorskip("trimesh")
    loaded = trimesh.load(trimesh.util.wrap_as_stream(glb_bytes(brush)), file_type="glb",
                          force="scene")
    clouds = [g for g in loaded.geometry.values() if isinstance(g, trimesh.PointCloud)]
    assert len(clouds) == 1 and len(clouds[0].vertices) == 200
    turned = brush.positions * np.array([-1, -1, 1], np.float32)
    np.testing.assert_allclose(np.sort(clouds[0].vertices, axis=0), np.sort(turned, axis=0),
                               atol=1e-6)


def test_write_scene_picks_the_format_by_extension(brush, tmp_path):
    for suffix, fmt in ((".ply", "ply"), (".SPZ", "spz"), (".glb", "glb"), (".splat", "splat")):
        path = tmp_path / f"out{suffix}"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataLossWarning)
            write_scene(brush, path)
        scene, source = read_scene_with_report(path)
        assert source.format == fmt and len(scene) == 200
    with pytest.raises(UnsupportedError, match=r"cannot write '\.obj'.*\.ply, \.splat"):
        write_scene(brush, tmp_path / "out.obj")
    assert not (tmp_path / "out.obj").exists()


def test_writers_say_what_the_format_drops(brush, tmp_path):
    with pytest.warns(DataLossWarning, match="SH bands 1-3"):
        write_scene(brush, tmp_path / "a.splat")
    labelled = brush.subset(np.arange(len(brush)))
    labelled.labels = np.arange(len(brush), dtype=np.int32)
    with pytest.warns(DataLossWarning, match="labels"):
        write_scene(labelled, tmp_path / "a.spz")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_scene(labelled, tmp_path / "a.ply")  # PLY carries everything
    back, _ = read_scene_with_report(tmp_path / "a.ply")
    np.testing.assert_array_equal(back.labels, labelled.labels)
    np.testing.assert_array_equal(back.sh_rest, labelled.sh_rest)
    assert read_scene_with_report(tmp_path / "a.spz")[0].labels is None
