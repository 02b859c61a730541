"""Paths the operating system refuses end in one line naming the path, exit 2 (issue #52,
items 6 and 7): names longer than a file system allows (ENAMETOOLONG) in every command's
path arguments and in the image names camera files hold, and outputs into folders that
cannot be written. The viewer's server answers such a path 404, not 500."""

from __future__ import annotations

import json
import os
import urllib.error
import urllib.request

import pytest

from csgs_cli.main import main
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.web.server import ViewerServer
from tests.codec.helpers import random_scene

LONG = "n" * 300  # longer than the 255 bytes a file name may have on common file systems


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "scene.ply"
    write_ply(random_scene(16, sh_degree=0), path)
    return path


def _one_line_exit_2(argv, fragment, capsys):
    assert main([*argv, "-q"]) == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1 and "Traceback" not in err
    return err


@pytest.mark.parametrize("argv", [
    ["info", "{dir}/" + LONG + ".csgs"],
    ["render", "{scene}", "--orbit", "1", "--size", "8x6", "-o", "{dir}/" + LONG],
    ["render", "{scene}", "--cameras", "{dir}/" + LONG + ".json", "-o", "{dir}/r"],
    ["segment", "{scene}", "--images", "{dir}/" + LONG, "-o", "{dir}/o.ply"],
    ["segment", "{scene}", "--images", "{dir}", "-o", "{dir}/" + LONG + ".ply"],
    ["synthetic", "{dir}/" + LONG],
    ["query", "{scene}", "--embedding", "{dir}/" + LONG + ".npy"],
    ["encode", "{scene}", "-o", "{dir}/" + LONG + ".csgs"],
    ["encode", "{scene}", "--cameras", "{dir}/" + LONG, "-o", "{dir}/x.csgs"],
])
def test_a_name_too_long_exits_2_naming_it(tmp_path, scene, capsys, argv):
    words = [w.format(dir=tmp_path, scene=scene) for w in argv]
    _one_line_exit_2(words, LONG, capsys)


def test_an_image_name_too_long_in_transforms_json_is_named(tmp_path, capsys):
    assert main(["synthetic", str(tmp_path), "--views", "2", "--size", "16x12",
                 "--gaussians", "10", "--objects", "1", "-q"]) == 0
    transforms = tmp_path / "transforms.json"
    document = json.loads(transforms.read_text())
    document["frames"][0]["file_path"] = LONG + ".png"
    transforms.write_text(json.dumps(document))
    err = _one_line_exit_2(["train", str(tmp_path), "-o", str(tmp_path / "x.csgs")], LONG,
                           capsys)
    assert "image" in err


def test_synthetic_into_a_folder_that_cannot_be_made_names_it(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_bytes(b"")
    _one_line_exit_2(["synthetic", str(blocker / "data")], "cannot create the folder",
                     capsys)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_synthetic_into_a_read_only_folder_names_it(tmp_path, capsys):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        _one_line_exit_2(["synthetic", str(folder)], "not writable", capsys)
    finally:
        folder.chmod(0o755)


def test_the_viewer_answers_a_name_too_long_with_404(tmp_path):
    with ViewerServer(None) as running:
        url = running.url + "web/" + "a" * 5000 + ".js"
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(url, timeout=30)
        assert err.value.code == 404
