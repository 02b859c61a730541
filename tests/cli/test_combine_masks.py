"""`csgs combine-masks`: SAM-style per-object binary masks become one id image per view that
`csgs segment --masks` reads (issue #55 item 5.4; rules in docs/masks.md)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from csgs_cli.main import main
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.train.combine_masks import id_png
from csgs_codec.train.image_files import read_mask
from csgs_codec.train.synthetic import make_synthetic_dataset
from tests.train.test_segment import _object_ious


def _binary(path, mask: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.where(mask, 255, 0).astype(np.uint8)).save(path)


def _square(shape, top, left, size) -> np.ndarray:
    mask = np.zeros(shape, dtype=bool)
    mask[top:top + size, left:left + size] = True
    return mask


def test_ids_follow_natural_order_and_the_smaller_object_wins(tmp_path, capsys):
    shape = (20, 30)
    objects = {"0.png": _square(shape, 0, 0, 12), "2.png": _square(shape, 15, 20, 4),
               "10.png": _square(shape, 2, 2, 5)}   # inside 0.png: the smaller wins
    for name, mask in objects.items():
        _binary(tmp_path / "sam" / "frame_001" / name, mask)
    (tmp_path / "sam" / "frame_001" / "metadata.csv").write_text("id,area\n")
    assert main(["combine-masks", str(tmp_path / "sam"), "-o", str(tmp_path / "masks")]) == 0
    expected = np.zeros(shape, dtype=np.int32)
    expected[objects["0.png"]] = 1
    expected[objects["2.png"]] = 2
    expected[objects["10.png"]] = 3
    written = tmp_path / "masks" / "frame_001.png"
    assert Image.open(written).mode == "L"
    assert np.array_equal(read_mask(written), expected)
    assert "--ignore-id 0" in capsys.readouterr().out


def test_of_two_objects_the_same_size_the_later_wins(tmp_path):
    shape = (10, 10)
    _binary(tmp_path / "sam" / "v" / "a.png", _square(shape, 0, 0, 6))
    _binary(tmp_path / "sam" / "v" / "b.png", _square(shape, 3, 3, 6))
    assert main(["combine-masks", "-q", str(tmp_path / "sam"), "-o", str(tmp_path / "m")]) == 0
    ids = read_mask(tmp_path / "m" / "v.png")
    assert ids[4, 4] == 2 and ids[0, 0] == 1 and ids[8, 8] == 2 and ids[9, 9] == 0


def test_mismatched_sizes_are_refused_naming_both_files(tmp_path, capsys):
    _binary(tmp_path / "sam" / "v" / "0.png", np.ones((10, 10), dtype=bool))
    _binary(tmp_path / "sam" / "v" / "1.png", np.ones((12, 10), dtype=bool))
    assert main(["combine-masks", "-q", str(tmp_path / "sam"), "-o", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err
    assert "1.png" in err and "0.png" in err and "10x12" in err and "10x10" in err
    assert err.count("\n") == 1 and not (tmp_path / "m" / "v.png").exists()


def test_a_mask_that_is_no_single_object_is_refused(tmp_path, capsys):
    """A photo or an id image in a view folder (the capture folder given by mistake)."""
    _binary(tmp_path / "sam" / "v" / "0.png", np.ones((4, 4), dtype=bool))
    Image.fromarray(np.arange(16, dtype=np.uint8).reshape(4, 4)).save(
        tmp_path / "sam" / "v" / "1.png")
    assert main(["combine-masks", "-q", str(tmp_path / "sam"), "-o", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err
    assert "not a binary object mask: 16 distinct values" in err and "1.png" in err


@pytest.mark.parametrize("layout", ["missing", "empty"])
def test_a_folder_without_view_folders_is_refused(tmp_path, capsys, layout):
    source = tmp_path / "sam"
    if layout == "empty":
        (source / "v").mkdir(parents=True)
        _binary(source / "loose.png", np.ones((4, 4), dtype=bool))
    assert main(["combine-masks", "-q", str(source), "-o", str(tmp_path / "m")]) == 2
    assert str(source) in capsys.readouterr().err


def test_more_than_255_ids_are_written_as_16_bit(tmp_path):
    ids = np.arange(600, dtype=np.int32).reshape(20, 30)
    (tmp_path / "m.png").write_bytes(id_png(ids))
    assert Image.open(tmp_path / "m.png").mode.startswith("I")
    assert np.array_equal(read_mask(tmp_path / "m.png"), ids)


def test_combined_sam_style_masks_segment_a_capture(tmp_path):
    """The walk: per-object masks of a capture -> combine-masks -> segment --masks."""
    dataset = make_synthetic_dataset(5, objects=3, gaussians_per_object=120, views=6,
                                     width=64, height=48)
    dataset.write(tmp_path / "capture")
    for view in dataset.views:
        stem = view.name.rsplit("/", 1)[-1].removesuffix(".png")
        for label in range(1, 4):
            _binary(tmp_path / "sam" / stem / f"{label}.png", view.mask == label)
    assert main(["combine-masks", "-q", str(tmp_path / "sam"), "-o", str(tmp_path / "ids")]) == 0
    for view in dataset.views:
        stem = view.name.rsplit("/", 1)[-1].removesuffix(".png")
        assert np.array_equal(read_mask(tmp_path / "ids" / f"{stem}.png"), view.mask)
    out = tmp_path / "segmented.ply"
    assert main(["segment", "-q", str(tmp_path / "capture" / "scene.ply"), "--images",
                 str(tmp_path / "capture"), "--masks", str(tmp_path / "ids"), "--ignore-id",
                 "0", "-o", str(out), "--iterations", "80"]) == 0
    rows, ids = np.unique(read_ply(out).semantic, axis=0, return_inverse=True)
    assert min(_object_ious(ids.reshape(-1), dataset.scene.labels)) > 0.9
