"""Finite but absurd intrinsics are refused when the camera file is read (issue #52, item
5): fl_x 1e-300 or cx 1e300 used to reach the rasterizer and overflow there, a traceback in
segment, render and train. The error names the file and the field."""

from __future__ import annotations

import json

import pytest

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.scene.cameras_io import load_cameras
from tests.codec.helpers import random_scene
from tests.colmap_model import ColmapCamera, ColmapImage, write_colmap_model

IDENTITY = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]


def _transforms(path, **fields):
    document = {"w": 64, "h": 48, "fl_x": 60.0, "fl_y": 60.0,
                "frames": [{"file_path": "a.png", "transform_matrix": IDENTITY}]}
    document.update(fields)
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize("field, value", [
    ("fl_x", 1e-300), ("fl_y", 1e300), ("cx", 1e300), ("cy", -1e300), ("fl_x", 1e-3),
])
def test_transforms_json_names_the_absurd_field(tmp_path, field, value):
    path = _transforms(tmp_path / "transforms.json", **{field: value})
    with pytest.raises(InputError, match="out of range|too far outside") as err:
        load_cameras(path)
    assert err.value.file == str(path) and err.value.property == f"frames[0].{field}"


def test_sane_intrinsics_still_load(tmp_path):
    path = _transforms(tmp_path / "transforms.json", cx=-10.0, cy=60.0, fl_x=5000.0)
    camera = load_cameras(path)[0]
    assert (camera.fx, camera.cx, camera.cy) == (5000.0, -10.0, 60.0)


def test_inria_cameras_json_names_the_absurd_focal(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps([{"width": 64, "height": 48, "fx": 1e-300, "fy": 60,
                                 "position": [0, 0, -3],
                                 "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}]))
    with pytest.raises(InputError, match="focal length 1e-300") as err:
        load_cameras(path)
    assert err.value.property == "[0].fx"


@pytest.mark.parametrize("binary", [False, True])
@pytest.mark.parametrize("params, field", [((1e-300, 1e-300, 32.0, 24.0), "fx"),
                                           ((60.0, 60.0, 1e300, 24.0), "cx")])
def test_colmap_names_the_absurd_parameter(tmp_path, binary, params, field):
    folder = write_colmap_model(
        tmp_path / "sparse", [ColmapCamera(1, "PINHOLE", 64, 48, params)],
        [ColmapImage(1, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 3.0), 1, "a.png")], binary=binary)
    with pytest.raises(InputError, match="camera 1: ") as err:
        load_cameras(folder)
    assert err.value.property == f"PARAMS ({field})"
    assert "cameras." in err.value.file


def test_render_exits_2_naming_the_field(tmp_path, capsys):
    scene = tmp_path / "scene.ply"
    write_ply(random_scene(16, sh_degree=0), scene)
    cameras = _transforms(tmp_path / "transforms.json", fl_x=1e-300)
    assert main(["render", str(scene), "--cameras", str(cameras), "-o", str(tmp_path / "r"),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert "frames[0].fl_x" in err and str(cameras) in err and err.count("\n") == 1
