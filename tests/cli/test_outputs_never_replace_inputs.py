"""No output may replace any input of its command (issue #52, item 1).

Each command declares every file it reads and every file it writes; an output that is one of
the inputs (same name, hard link or symlink) is refused before any work with exit 2, one line
naming the output, its option and the input, and the input left as it was.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_cli.output_guard import refuse_overwriting_inputs
from csgs_codec.interchange.ply_io import write_ply
from tests.codec.helpers import random_scene


@pytest.fixture
def files(tmp_path):
    scene = tmp_path / "scene.ply"
    write_ply(random_scene(32, sh_degree=0), scene)
    query = tmp_path / "q.npy"
    np.save(query, np.ones(4, dtype=np.float32))
    cameras = tmp_path / "cams.json"
    cameras.write_text('[{"width": 8, "height": 6, "fx": 5, "fy": 5, "position": [0, 0, -3],'
                       ' "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}]')
    return {"scene": scene, "query": query, "cameras": cameras}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("synthetic")
    assert main(["synthetic", str(folder), "--views", "3", "--size", "16x12",
                 "--gaussians", "20", "--objects", "1", "-q"]) == 0
    return folder


def assert_refused(argv, victim, option, capsys):
    before = victim.read_bytes()
    assert main([*argv, "-q"]) == 2
    err = capsys.readouterr().err
    assert "is the input file" in err and option in err and str(victim.name) in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert victim.read_bytes() == before


@pytest.mark.parametrize("how", ["same", "hardlink", "symlink"])
def test_query_output_is_not_the_query_embedding(files, tmp_path, capsys, how):
    out = files["query"]
    if how != "same":
        out = tmp_path / "out.ply"
        (os.link if how == "hardlink" else os.symlink)(files["query"], out)
    assert_refused(["query", str(files["scene"]), "--embedding", str(files["query"]), "-o",
              str(out)], files["query"], "-o", capsys)


@pytest.mark.parametrize("view", ["{}", "{}#0"])
def test_select_output_is_not_the_view_cameras(files, capsys, view):
    cameras = str(files["cameras"])
    assert_refused(["select", str(files["scene"]), "--view", view.format(cameras), "--click", "1,1",
              "-o", cameras], files["cameras"], "-o", capsys)


def test_select_mask_is_not_the_scene(files, tmp_path, capsys):
    assert_refused(["select", str(files["scene"]), "--view", "orbit:0", "--click", "1,1", "-o",
              str(tmp_path / "o.ply"), "--save-mask", str(files["scene"])], files["scene"],
             "--save-mask", capsys)


def test_two_outputs_of_one_command_are_refused(files, tmp_path, capsys):
    out = tmp_path / "o.ply"
    assert main(["select", str(files["scene"]), "--view", "orbit:0", "--click", "1,1", "-o",
                 str(out), "--save-mask", str(out), "-q"]) == 2
    assert "is also the output of -o" in capsys.readouterr().err
    assert not out.exists()


def test_view_screenshot_is_not_the_scene(files, capsys):
    assert_refused(["view", str(files["scene"]), "--screenshot", str(files["scene"])],
             files["scene"], "--screenshot", capsys)


def test_encode_output_is_not_the_cameras(files, capsys):
    assert_refused(["encode", str(files["scene"]), "--cameras", str(files["cameras"]), "-o",
              str(files["cameras"])], files["cameras"], "-o", capsys)


def test_render_output_images_are_not_the_cameras(files, tmp_path, capsys):
    # render names its images after the cameras' (this one's: its index, 0): a cameras file
    # by that name is an input
    cameras = tmp_path / "0.png"
    cameras.write_bytes(files["cameras"].read_bytes())
    assert_refused(["render", str(files["scene"]), "--cameras", str(cameras), "-o", str(tmp_path)],
             cameras, "-o", capsys)


@pytest.mark.parametrize("victim", ["transforms.json", "images/000.png", "masks/000.png",
                                    "points"])
def test_train_output_is_no_file_of_the_dataset(dataset, tmp_path, capsys, victim):
    extra = []
    if victim == "points":
        points = tmp_path / "points.ply"
        write_ply(random_scene(8, sh_degree=0), points)
        target, extra = points, ["--points", str(points)]
    else:
        target = next(dataset.glob(victim.replace("000", "*")))
    assert_refused(["train", str(dataset), "-o", str(target), *extra], target, "-o", capsys)


def test_segment_output_is_no_file_of_the_capture(files, dataset, capsys):
    image = next(dataset.glob("images/*"))
    link = dataset / "link.ply"
    link.unlink(missing_ok=True)
    os.symlink(image, link)
    assert_refused(["segment", str(files["scene"]), "--images", str(dataset), "-o", str(link)],
             image, "-o", capsys)


def test_a_file_a_scene_folder_reads_is_protected_and_others_are_not(tmp_path, capsys):
    folder = tmp_path / "inria"
    cloud = folder / "point_cloud" / "iteration_7" / "point_cloud.ply"
    cloud.parent.mkdir(parents=True)
    write_ply(random_scene(32, sh_degree=0), cloud)
    (folder / "cameras.json").write_text("[]")
    assert_refused(["encode", str(folder), "-o", str(folder / "cameras.json")],
             folder / "cameras.json", "-o", capsys)
    earlier = folder / "scene.csgs"  # an earlier run's output kept in the folder
    earlier.write_bytes(b"old")
    refuse_overwriting_inputs([("-o", earlier)], [("the scene", folder)])
