"""Image paths in a camera file stay inside the dataset folder unless the user allows
otherwise (``allow_outside_paths`` / ``--allow-outside-paths``; docs/captures.md)."""

from __future__ import annotations

import json
import shutil

import pytest

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.train.datasets import load_dataset
from tests.fuzz.loader_seeds import loader_seeds


def _capture(tmp_path, layout: str):
    seed = next(s for s in loader_seeds() if s.format == layout)
    root = tmp_path / "data" / layout
    for name, data in seed.files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(data)
    return root


def _move_first_image_out(root, tmp_path):
    """view_000.png moved to a folder beside the dataset; returns its new path."""
    outside = tmp_path / "data" / "elsewhere"
    outside.mkdir()
    return shutil.move(root / "images" / "view_000.png", outside / "view_000.png")


def assert_refused(root, *fragments: str) -> None:
    with pytest.raises(InputError) as caught:
        load_dataset(root, segment_missing=False)
    for fragment in fragments:
        assert fragment in str(caught.value)
    views = load_dataset(root, segment_missing=False, allow_outside_paths=True)
    assert [v.image.shape for v in views] == [(6, 8, 3)] * 3


@pytest.mark.parametrize("absolute", [False, True])
def test_transforms_frame_leaving_the_folder_is_refused_unless_allowed(tmp_path, absolute):
    root = _capture(tmp_path, "transforms")
    moved = _move_first_image_out(root, tmp_path)
    document = json.loads((root / "transforms.json").read_text())
    name = str(moved) if absolute else "../elsewhere/view_000.png"
    document["frames"][0]["file_path"] = name
    (root / "transforms.json").write_text(json.dumps(document))
    assert_refused(root, "transforms.json", "frames[0].file_path", repr(name),
             "--allow-outside-paths")


def test_inria_img_name_climbing_out_is_refused_unless_allowed(tmp_path):
    root = _capture(tmp_path, "inria")
    _move_first_image_out(root, tmp_path)
    entries = json.loads((root / "cameras.json").read_text())
    entries[0]["img_name"] = "../../elsewhere/view_000"  # relative to images/
    (root / "cameras.json").write_text(json.dumps(entries))
    assert_refused(root, "cameras.json", "[0].img_name", "'../../elsewhere/view_000'")


def test_colmap_image_name_climbing_out_is_refused_unless_allowed(tmp_path):
    root = _capture(tmp_path, "colmap-text")
    _move_first_image_out(root, tmp_path)
    images = root / "sparse" / "0" / "images.txt"
    images.write_text(images.read_text().replace("view_000.png",
                                                 "../../elsewhere/view_000.png"))
    assert_refused(root, "images.txt", "image ../../elsewhere/view_000.png")


def test_names_that_climb_but_stay_inside_load(tmp_path):
    root = _capture(tmp_path, "inria")
    shutil.move(root / "images" / "view_001.png", root / "view_001.png")
    entries = json.loads((root / "cameras.json").read_text())
    entries[1]["img_name"] = "../view_001"  # relative to images/: the dataset folder
    (root / "cameras.json").write_text(json.dumps(entries))
    assert len(load_dataset(root, segment_missing=False)) == 3


def test_a_symlinked_image_folder_loads(tmp_path):
    # The rule reads the names as written: the dataset's own links are its layout.
    root = _capture(tmp_path, "colmap-binary")
    store = tmp_path / "store"
    shutil.move(root / "images", store)
    (root / "images").symlink_to(store, target_is_directory=True)
    assert len(load_dataset(root, segment_missing=False)) == 3


def test_an_explicit_images_folder_is_the_folder_names_stay_in(tmp_path):
    root = _capture(tmp_path, "transforms")
    renders = tmp_path / "renders"
    shutil.copytree(root / "images", renders / "images")
    # the given folder lies outside the camera file's: allowed, it was named explicitly
    views = load_dataset(root / "transforms.json", images=renders, segment_missing=False)
    assert len(views) == 3
    document = json.loads((root / "transforms.json").read_text())
    document["frames"][2]["file_path"] = "../transforms/images/view_002.png"
    (root / "transforms.json").write_text(json.dumps(document))
    with pytest.raises(InputError, match="frames\\[2\\].file_path"):
        load_dataset(root / "transforms.json", images=renders, segment_missing=False)


def test_csgs_train_refuses_in_one_line_and_the_option_lets_it_read(tmp_path, capsys):
    root = _capture(tmp_path, "transforms")
    moved = _move_first_image_out(root, tmp_path)
    document = json.loads((root / "transforms.json").read_text())
    document["frames"][0]["file_path"] = str(moved)
    (root / "transforms.json").write_text(json.dumps(document))
    out = tmp_path / "x.csgs"
    args = ["train", str(root), "-o", str(out), "--iterations", "1", "-q",
            "--no-foreground-masks"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "frames[0].file_path" in err and "--allow-outside-paths" in err
    assert not out.exists()
    assert main([*args, "--allow-outside-paths"]) == 0
    assert out.is_file()
