"""`csgs segment` without masks says that the built-in segmenter took their place, even under
--quiet (issue #55 item 5.1): where it looked, how to give masks; --builtin-segmenter accepts
the fallback silently."""

from __future__ import annotations

import shutil

import pytest

from csgs_cli.main import main
from csgs_codec.train.synthetic import make_synthetic_dataset


@pytest.fixture(scope="module")
def capture_without_masks(tmp_path_factory):
    folder = tmp_path_factory.mktemp("no_masks")
    make_synthetic_dataset(1, objects=2, gaussians_per_object=40, views=2, width=32,
                           height=24).write(folder)
    shutil.rmtree(folder / "masks")
    return folder


def _segment(folder, out, *extra):
    return main(["segment", "-q", str(folder / "scene.ply"), "--images", str(folder), "-o",
                 str(out), "--iterations", "3", *extra])


def test_missing_masks_warn_under_quiet_naming_where_and_how(capture_without_masks, tmp_path,
                                                             capsys):
    assert _segment(capture_without_masks, tmp_path / "out.ply") == 0
    err = capsys.readouterr().err
    assert "built-in graph segmenter" in err
    assert str(capture_without_masks / "masks") in err
    assert str(capture_without_masks.parent / "masks") in err
    assert "--masks DIR" in err and "--builtin-segmenter" in err
    assert len(err.strip().splitlines()) == 1


def test_builtin_segmenter_flag_accepts_the_fallback_silently(capture_without_masks, tmp_path,
                                                              capsys):
    assert _segment(capture_without_masks, tmp_path / "out.ply", "--builtin-segmenter") == 0
    assert capsys.readouterr().err == ""
    assert (tmp_path / "out.ply").is_file()


def test_masks_found_beside_the_images_give_no_warning(tmp_path, capsys):
    make_synthetic_dataset(1, objects=2, gaussians_per_object=40, views=2, width=32,
                           height=24).write(tmp_path)
    assert _segment(tmp_path, tmp_path / "out.ply") == 0
    assert "segmenter" not in capsys.readouterr().err
