"""`csgs render --cameras FILE` names each view after its camera's image, so `csgs segment
--images DIR --cameras FILE` finds the renders with the same cameras file (issue #55 item
5.2); names never lead outside the output folder, and never onto the capture's photos."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from csgs_cli.commands.render import image_file_names
from csgs_cli.main import main
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.train.synthetic import make_synthetic_dataset
from tests.train.test_segment import _object_ious


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    folder = tmp_path_factory.mktemp("capture")
    dataset = make_synthetic_dataset(3, objects=3, gaussians_per_object=120, views=6,
                                     width=64, height=48)
    dataset.write(folder)
    return dataset, folder


def _inria_cameras(dataset, path):
    """The capture's cameras as an INRIA cameras.json naming each image by its stem."""
    entries = []
    for i, view in enumerate(dataset.views):
        camera, pose = view.camera, view.camera.camera_to_world
        entries.append({"id": i, "img_name": view.name.split("/")[-1].removesuffix(".png"),
                        "width": camera.width, "height": camera.height, "fx": camera.fx,
                        "fy": camera.fy, "position": pose[:3, 3].tolist(),
                        "rotation": pose[:3, :3].tolist()})
    path.write_text(json.dumps(entries))
    return path


@pytest.mark.parametrize("layout", ["transforms", "inria"])
def test_segment_finds_what_render_wrote_with_the_same_cameras_file(capture, tmp_path, layout):
    dataset, folder = capture
    renders = tmp_path / "renders"
    cameras = (folder / "transforms.json" if layout == "transforms"
               else _inria_cameras(dataset, tmp_path / "cameras.json"))
    assert main(["render", "-q", str(folder / "scene.ply"), "--cameras", str(cameras),
                 "-o", str(renders)]) == 0
    written = sorted(p.relative_to(renders).as_posix() for p in renders.rglob("*.png"))
    prefix = "images/" if layout == "transforms" else ""
    assert written == [f"{prefix}view_{i:03d}.png" for i in range(6)]
    out = tmp_path / "segmented.ply"
    assert main(["segment", "-q", str(folder / "scene.ply"), "--images", str(renders),
                 "--cameras", str(cameras), "--masks", str(folder / "masks"), "-o", str(out),
                 "--iterations", "80"]) == 0
    rows, ids = np.unique(read_ply(out).semantic, axis=0, return_inverse=True)
    assert len(rows) == 3
    assert min(_object_ious(ids.reshape(-1), dataset.scene.labels)) > 0.9


def test_segment_with_cameras_names_the_missing_render(capture, tmp_path, capsys):
    _, folder = capture
    (tmp_path / "renders").mkdir()
    assert main(["segment", "-q", str(folder / "scene.ply"), "--images",
                 str(tmp_path / "renders"), "--cameras", str(folder / "transforms.json"),
                 "--masks", str(folder / "masks"), "-o", str(tmp_path / "x.ply")]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "renders" / "images" / "view_000.png") in err
    assert err.count("\n") == 1


def test_render_refuses_to_replace_the_capture_photos(capture, capsys):
    _, folder = capture
    before = (folder / "images" / "view_000.png").read_bytes()
    assert main(["render", "-q", str(folder / "scene.ply"), "--cameras",
                 str(folder / "transforms.json"), "-o", str(folder)]) == 2
    assert "is the input file" in capsys.readouterr().err
    assert (folder / "images" / "view_000.png").read_bytes() == before


@pytest.mark.parametrize(("name", "file"), [
    ("images/frame_001.jpg", "images/frame_001.png"),   # transforms file_path, COLMAP
    ("./train/r_0", "train/r_0.png"),                   # Blender: no suffix
    ("frame_001", "frame_001.png"),                     # INRIA img_name
    ("DSC.0042.JPG", "DSC.0042.png"),
    ("shot.v2", "shot.v2.png"),                         # not an image suffix: kept
    ("/data/capture/images/a.png", "a.png"),            # absolute: its file name only
    ("../../etc/b.png", "b.png"),                       # climbing out: its file name only
    ("images/../../c.jpeg", "c.png"),
])
def test_own_names_stay_inside_the_output_folder(name, file):
    assert image_file_names([SimpleNamespace(name=name)], own_names=True) == [file]


def test_repeated_names_fall_back_to_numbered_files():
    cameras = [SimpleNamespace(name=n) for n in ("a/x.jpg", "a/x.png", "orbit_1")]
    with pytest.warns(UserWarning, match="repeat"):
        names = image_file_names(cameras[:2], own_names=True)
    assert names == ["000_x.png", "001_x.png"]
    assert image_file_names(cameras[2:], own_names=False) == ["orbit_1.png"]
