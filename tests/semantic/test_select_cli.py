"""`csgs select`: writes the clicked object's Gaussians as a PLY; bad input exits 2 with one
line and writes nothing."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.codec.encoder import Encoder
from csgs_codec.interchange.ply_io import read_ply, write_ply
from csgs_codec.scene.cameras_io import resize_camera
from csgs_codec.semantic.synthetic import labelled_blob_scene
from tests.semantic.scenes import (
    background_pixel,
    centre_pixel,
    five_objects,
    write_inria_cameras,
)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("select")
    scene, camera = five_objects()
    ply = folder / "objects.ply"
    write_ply(scene, ply)
    csgs = folder / "objects.csgs"
    csgs.write_bytes(Encoder(quality=5).encode(scene))
    other = resize_camera(camera, 160, 120)
    cameras = write_inria_cameras([other, camera], folder / "cameras.json")
    return {"scene": scene, "camera": camera, "ply": ply, "csgs": csgs, "cameras": cameras}


def click_text(point) -> str:
    return f"{point[0]:.1f},{point[1]:.1f}"


@pytest.mark.parametrize("mode", ["instance", "cosine"])
@pytest.mark.parametrize("source", ["ply", "csgs"])
def test_select_writes_the_clicked_objects_gaussians(files, tmp_path, capsys, source, mode):
    scene, camera = files["scene"], files["camera"]
    out = tmp_path / "object.ply"
    click = click_text(centre_pixel(scene, camera, 3))
    assert main(["select", str(files[source]), "--view", f"{files['cameras']}#1",
                 "--click", click, "--mode", mode, "-o", str(out)]) == 0
    selected = read_ply(out)
    truth = int(np.count_nonzero(scene.labels == 3))
    if mode == "instance":  # the labels are the instances: exactly the object
        assert len(selected) == truth
    else:
        assert 0.9 * truth <= len(selected) <= truth / 0.9
    assert set(np.unique(selected.labels)) == {3}
    assert selected.semantic is not None and selected.semantic.shape[1] == 6
    text = capsys.readouterr().out
    assert f"selected {len(selected):,} of {len(scene):,} Gaussians" in text
    assert ("instance from labels" in text) == (mode == "instance")


def test_select_by_camera_name_and_resized_click(files, tmp_path):
    scene, camera = files["scene"], files["camera"]
    out = tmp_path / "object.ply"
    x, y = centre_pixel(scene, camera, 0)
    assert main(["select", "-q", str(files["ply"]), "--view", f"{files['cameras']}#overview",
                 "--size", "640x480", "--click", f"{2 * x:.1f},{2 * y:.1f}", "--mode",
                 "cluster", "-o", str(out)]) == 0
    assert set(np.unique(read_ply(out).labels)) == {0}


def test_select_in_an_orbit_view(tmp_path):
    scene = labelled_blob_scene(1, 300, seed=5)
    path = tmp_path / "one.ply"
    write_ply(scene, path)
    out = tmp_path / "object.ply"
    assert main(["select", "-q", str(path), "--view", "orbit:2", "--orbit", "4", "--size",
                 "120x90", "--click", "60,45", "-o", str(out)]) == 0
    assert len(read_ply(out)) >= 0.9 * len(scene)


def test_select_saves_the_mask(files, tmp_path):
    scene, camera = files["scene"], files["camera"]
    mask_path = tmp_path / "mask.npy"
    assert main(["select", "-q", str(files["ply"]), "--view", str(files["cameras"]) + "#1",
                 "--click", click_text(centre_pixel(scene, camera, 1)), "--save-mask",
                 str(mask_path), "-o", str(tmp_path / "o.ply")]) == 0
    mask = np.load(mask_path)
    assert mask.dtype == np.bool_ and mask.shape == (len(scene),)
    assert set(np.unique(scene.labels[mask])) == {1}


@pytest.mark.parametrize("view, click, message", [
    ("#1", "5000,10", "outside the 320x240 image"),
    ("#1", "ten,10", "click must look like"),
    ("#1", None, "nothing under the click"),
    ("#7", "10,10", "camera 7 does not exist"),
    ("#nope", "10,10", "no camera named 'nope'"),
    ("orbit:20", "10,10", "orbit view 20 does not exist"),
])
def test_select_bad_input_exits_2_with_one_line(files, tmp_path, capsys, view, click,
                                                message):
    out = tmp_path / "object.ply"
    click = click or click_text(background_pixel(files["camera"]))
    spec = view if view.startswith("orbit") else f"{files['cameras']}{view}"
    assert main(["select", str(files["ply"]), "--view", spec, "--click", click,
                 "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_select_on_a_scene_without_semantic_features_exits_2(files, tmp_path, capsys):
    bare = files["scene"].subset(np.arange(len(files["scene"])))
    bare.semantic, bare.semantic_names, bare.labels = None, (), None
    path = tmp_path / "bare.ply"
    write_ply(bare, path)
    assert main(["select", str(path), "--view", str(files["cameras"]), "--click", "10,10",
                 "-o", str(tmp_path / "o.ply")]) == 2
    assert "no labels or semantic features" in capsys.readouterr().err


def test_select_missing_scene_and_folder_output_exit_2(files, tmp_path, capsys):
    assert main(["select", str(tmp_path / "none.ply"), "--view", "orbit:0", "--click", "1,1",
                 "-o", str(tmp_path / "o.ply")]) == 2
    assert "none.ply: file not found" in capsys.readouterr().err
    assert main(["select", str(files["ply"]), "--view", "orbit:0", "--click", "1,1",
                 "-o", str(tmp_path)]) == 2
    assert "output is a folder" in capsys.readouterr().err
