"""Camera loaders: each format gives the right intrinsics and poses; bad files name the field."""

from __future__ import annotations

import json
import shutil
import struct
import warnings

import numpy as np
import pytest

from csgs_codec.errors import CsgsWarning, InputError, UnsupportedError
from csgs_codec.scene.cameras_io import load_cameras, resize_camera
from tests.colmap_model import ColmapCamera, ColmapImage, write_colmap_model
from tests.conftest import REPO
from tests.render.synthetic import project

CAMERA_DATA = REPO / "tests" / "data" / "cameras"
# Both fixture files describe the same two cameras:
#   view_a: 640x480, fx 500, fy 510, principal point (320, 240), centre (4, 0, 0), looking at
#           the origin along -x with world +z up; world +y is to the right in the image.
#   view_b: 320x240, f 250, principal point (160, 120), centre (0, 0, 3) looking down -z,
#           world +y up in the image.
VIEW_A_POINTS = {(0.0, 0.0, 0.0): (320.0, 240.0), (0.0, 1.0, 0.5): (445.0, 176.25)}
VIEW_B_POINTS = {(0.0, 0.0, 0.0): (160.0, 120.0), (1.0, 1.0, 0.0): (160 + 250 / 3, 120 - 250 / 3)}


def check_two_views(cameras) -> None:
    a, b = sorted(cameras, key=lambda c: c.width, reverse=True)
    assert (a.width, a.height, a.fx, a.fy, a.cx, a.cy) == (640, 480, 500, 510, 320, 240)
    assert (b.width, b.height, b.fx, b.fy, b.cx, b.cy) == (320, 240, 250, 250, 160, 120)
    np.testing.assert_allclose(a.position, [4, 0, 0], atol=1e-12)
    np.testing.assert_allclose(b.position, [0, 0, 3], atol=1e-12)
    for camera, known in ((a, VIEW_A_POINTS), (b, VIEW_B_POINTS)):
        for point, pixel in known.items():
            np.testing.assert_allclose(project(camera, point)[0], pixel, atol=1e-9)


def test_inria_cameras_json_gives_known_projections():
    cameras = load_cameras(CAMERA_DATA / "inria_cameras.json")
    check_two_views(cameras)
    assert [c.name for c in cameras] == ["view_a", "view_b"]


def test_transforms_json_converts_opengl_axes_to_opencv():
    check_two_views(load_cameras(CAMERA_DATA / "transforms.json"))


def test_transforms_json_focal_from_camera_angle(tmp_path):
    doc = json.loads((CAMERA_DATA / "transforms.json").read_text())
    for key in ("fl_x", "fl_y", "cx", "cy"):
        doc.pop(key)
    doc["camera_angle_x"] = 2 * np.arctan(320 / 500)
    doc["frames"] = doc["frames"][:1]
    path = tmp_path / "transforms.json"
    path.write_text(json.dumps(doc))
    (camera,) = load_cameras(path)
    assert camera.fx == pytest.approx(500) and camera.fy == pytest.approx(500)
    assert (camera.cx, camera.cy) == (320, 240)


def test_transforms_json_warns_about_distortion(tmp_path):
    doc = json.loads((CAMERA_DATA / "transforms.json").read_text())
    doc["k1"] = 0.1
    path = tmp_path / "transforms.json"
    path.write_text(json.dumps(doc))
    with pytest.warns(CsgsWarning, match="distortion"):
        cameras = load_cameras(path)
    assert len(cameras) == len(doc["frames"])  # still loaded, distortion ignored


def test_colmap_text_model_gives_known_projections():
    with pytest.warns(CsgsWarning, match="SIMPLE_RADIAL"):
        cameras = load_cameras(CAMERA_DATA / "colmap_text")
    check_two_views(cameras)
    assert [c.name for c in cameras] == ["view_a.png", "view_b.png"]  # sorted by name


def test_colmap_text_loads_from_either_file_and_sparse_zero(tmp_path):
    sparse = tmp_path / "scene" / "sparse" / "0"
    shutil.copytree(CAMERA_DATA / "colmap_text", sparse)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CsgsWarning)
        check_two_views(load_cameras(tmp_path / "scene"))
        check_two_views(load_cameras(sparse / "images.txt"))


def write_colmap_binary(folder, *, truncate: int = 0, model_id: int = 1) -> None:
    """Two views: a PINHOLE (or ``model_id``) camera with two 2D points and a
    SIMPLE_PINHOLE one."""
    cameras = [ColmapCamera(1, model_id, 640, 480, (500, 510, 320, 240)),
               ColmapCamera(2, "SIMPLE_PINHOLE", 320, 240, (250, 160, 120))]
    images = [ColmapImage(1, (0.5, 0.5, 0.5, -0.5), (0, 0, 4), 1, "view_a.png",
                          [(1.5, 2.5, -1)] * 2),
              ColmapImage(2, (0, 1, 0, 0), (0, 0, 3), 2, "view_b.png")]
    write_colmap_model(folder, cameras, images, binary=True, truncate=truncate)


def test_colmap_binary_model_gives_known_projections(tmp_path):
    write_colmap_binary(tmp_path / "model")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pinhole models: nothing to warn about
        cameras = load_cameras(tmp_path / "model" / "cameras.bin")
    check_two_views(cameras)


def test_colmap_binary_truncated_names_field_and_offset(tmp_path):
    write_colmap_binary(tmp_path / "model", truncate=5)
    with pytest.raises(InputError, match=r"images\.bin.*byte \d+.*num_points2D"):
        load_cameras(tmp_path / "model")


def test_colmap_binary_unknown_model_is_unsupported(tmp_path):
    write_colmap_binary(tmp_path / "model", model_id=42)
    with pytest.raises(UnsupportedError, match="model id 42"):
        load_cameras(tmp_path / "model")


def test_colmap_binary_huge_count_is_rejected_before_allocating(tmp_path):
    write_colmap_binary(tmp_path / "model")
    (tmp_path / "model" / "images.bin").write_bytes(struct.pack("<Q", 1 << 60))
    with pytest.raises(InputError, match="num_reg_images"):
        load_cameras(tmp_path / "model")


@pytest.mark.parametrize(("line", "field"), [
    ("1 PINHOLE 640 480 500 510 320", "PARAMS"),
    ("1 PINHOLE 640 480 500 510 320 abc", "PARAMS"),
    ("x PINHOLE 640 480 500 510 320 240", "CAMERA_ID"),
    ("1 PINHOLE 0 480 500 510 320 240", "WIDTH/HEIGHT"),
    ("1 PINHOLE 640 480 -500 510 320 240", "PARAMS"),
])
def test_colmap_text_bad_camera_line_names_field(tmp_path, line, field):
    shutil.copytree(CAMERA_DATA / "colmap_text", tmp_path / "m")
    (tmp_path / "m" / "cameras.txt").write_text(line + "\n")
    with pytest.raises(InputError) as info:
        load_cameras(tmp_path / "m")
    assert info.value.property == field and info.value.file.endswith("cameras.txt")


def test_colmap_text_unknown_model_is_unsupported(tmp_path):
    shutil.copytree(CAMERA_DATA / "colmap_text", tmp_path / "m")
    (tmp_path / "m" / "cameras.txt").write_text("1 WEIRD 640 480 1 2 3\n")
    with pytest.raises(UnsupportedError, match="WEIRD"):
        load_cameras(tmp_path / "m")


@pytest.mark.filterwarnings("ignore::csgs_codec.errors.CsgsWarning")
def test_colmap_text_image_with_unknown_camera_names_field(tmp_path):
    shutil.copytree(CAMERA_DATA / "colmap_text", tmp_path / "m")
    (tmp_path / "m" / "images.txt").write_text("1 1 0 0 0 0 0 0 9 a.png\n\n")
    with pytest.raises(InputError, match="camera 9") as info:
        load_cameras(tmp_path / "m")
    assert info.value.property == "CAMERA_ID"


@pytest.mark.parametrize(("edit", "field"), [
    (lambda e: e.pop("fx"), "[0].fx"),
    (lambda e: e.update(width=-3), "[0].width"),
    (lambda e: e.update(position=[1, 2]), "[0].position"),
    (lambda e: e.update(rotation=[[2, 0, 0], [0, 1, 0], [0, 0, 1]]), "[0].rotation"),
    (lambda e: e.update(fy="wide"), "[0].fy"),
])
def test_inria_bad_field_is_named(tmp_path, edit, field):
    entries = json.loads((CAMERA_DATA / "inria_cameras.json").read_text())
    edit(entries[0])
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps(entries))
    with pytest.raises(InputError) as info:
        load_cameras(path)
    assert info.value.property == field and info.value.file == str(path)


@pytest.mark.parametrize(("edit", "field"), [
    (lambda d: d["frames"][0].update(transform_matrix=[[1, 0], [0, 1]]),
     "frames[0].transform_matrix"),
    (lambda d: d.pop("w"), "frames[0].w"),
    (lambda d: [d.pop(k) for k in ("fl_x", "fl_y")], "frames[0].fl_x"),
    (lambda d: d.update(frames=[]), "frames"),
    (lambda d: [d.pop(k) for k in ("fl_x", "fl_y")] and d.update(camera_angle_x=4.0),
     "frames[0].camera_angle_x"),
])
def test_transforms_bad_field_is_named(tmp_path, edit, field):
    doc = json.loads((CAMERA_DATA / "transforms.json").read_text())
    edit(doc)
    path = tmp_path / "transforms.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError) as info:
        load_cameras(path)
    assert info.value.property == field


def test_invalid_json_names_line(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_text('[{"fx": 1,}]')
    with pytest.raises(InputError, match=r"cameras\.json.*line 1"):
        load_cameras(path)


def test_unrecognised_camera_file_is_an_input_error(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_text('{"cameras": []}')
    with pytest.raises(InputError, match="not a camera file"):
        load_cameras(path)
    with pytest.raises(InputError, match="no such file"):
        load_cameras(tmp_path / "missing.json")


def test_resize_camera_scales_intrinsics_and_keeps_pose():
    camera = load_cameras(CAMERA_DATA / "inria_cameras.json")[0]
    half = resize_camera(camera, 320, 240)
    assert (half.fx, half.fy, half.cx, half.cy) == (250, 255, 160, 120)
    np.testing.assert_allclose(project(half, (0, 1, 0.5)), project(camera, (0, 1, 0.5)) / 2)


def test_colmap_binary_every_truncation_is_an_input_error(tmp_path):
    write_colmap_binary(tmp_path / "good")
    for name in ("cameras.bin", "images.bin"):
        data = (tmp_path / "good" / name).read_bytes()
        for cut in range(len(data)):
            folder = tmp_path / f"{name}_{cut}"
            write_colmap_binary(folder)
            (folder / name).write_bytes(data[:cut])
            with pytest.raises(InputError):
                load_cameras(folder)


def test_camera_file_that_is_not_text_is_an_input_error(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(InputError, match="cannot read camera file"):
        load_cameras(path)


def test_transforms_json_without_size_reads_it_from_the_image(tmp_path):
    from PIL import Image

    doc = {"camera_angle_x": 2 * np.arctan(0.5),
           "frames": [{"file_path": "./train/r_0",
                       "transform_matrix": np.eye(4).tolist()}]}
    (tmp_path / "train").mkdir()
    Image.new("RGB", (40, 30)).save(tmp_path / "train" / "r_0.png")
    path = tmp_path / "transforms_train.json"
    path.write_text(json.dumps(doc))
    (camera,) = load_cameras(path)
    assert (camera.width, camera.height, camera.cx) == (40, 30, 20)
    assert camera.fx == pytest.approx(40) and camera.fy == pytest.approx(40)
    (tmp_path / "train" / "r_0.png").unlink()
    with pytest.raises(InputError) as info:
        load_cameras(path)
    assert info.value.property == "frames[0].w"
