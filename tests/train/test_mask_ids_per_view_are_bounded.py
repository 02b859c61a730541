"""Mask pairs grow as the square of a view's mask ids (issue #52, item 4): a view with more
than MAX_MASKS_PER_VIEW ids is refused by name when loaded, and ViewBatch refuses it (and a
total of pairs over MAX_MASK_PAIRS) before making the pair lists."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.train import semantic_batch
from csgs_codec.train.datasets import load_dataset
from csgs_codec.train.semantic_batch import MAX_MASKS_PER_VIEW, ViewBatch
from csgs_codec.train.synthetic import make_synthetic_dataset, write_transforms_dataset

WIDTH, HEIGHT = 64, 48  # 3,072 pixels: room for more ids than a view may hold


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(5, objects=2, gaussians_per_object=30, views=2, width=WIDTH,
                                  height=HEIGHT)


def _many_ids_mask(path):
    ids = np.arange(WIDTH * HEIGHT, dtype=np.uint16).reshape(HEIGHT, WIDTH)
    Image.fromarray(ids).save(path)  # 16-bit grey: the value is the id


def test_a_mask_with_too_many_ids_is_named_when_loaded(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    mask = next((tmp_path / "masks").glob("*.png"))
    _many_ids_mask(mask)
    with pytest.raises(InputError, match=f"3,072 ids, more than the {MAX_MASKS_PER_VIEW:,}") \
            as err:
        load_dataset(tmp_path)
    assert err.value.file == str(mask)


def test_segment_exits_2_naming_the_mask(tmp_path, synthetic, capsys):
    write_transforms_dataset(synthetic.views, tmp_path)
    mask = next((tmp_path / "masks").glob("*.png"))
    _many_ids_mask(mask)
    scene = tmp_path / "scene.ply"
    write_ply(synthetic.scene, scene)
    assert main(["segment", str(scene), "--images", str(tmp_path), "-o",
                 str(tmp_path / "out.ply"), "-q"]) == 2
    err = capsys.readouterr().err
    assert str(mask) in err and "3,072 ids" in err and err.count("\n") == 1


def _batch(ids_per_view: list[int]) -> ViewBatch:
    contributions, masks = [], []
    for count in ids_per_view:
        mask = torch.arange(count).reshape(1, count)
        contributions.append(torch.sparse_coo_tensor(
            torch.stack([torch.arange(count), torch.zeros(count, dtype=torch.int64)]),
            torch.ones(count), (count, 1), check_invariants=True))
        masks.append(mask)
    return ViewBatch.from_views(contributions, masks, 1)


def test_view_batch_refuses_too_many_ids_in_one_view():
    with pytest.raises(InputError, match=r"view 1: 2,049 mask ids"):
        _batch([3, MAX_MASKS_PER_VIEW + 1])


def test_view_batch_refuses_too_many_pairs_over_all_views(monkeypatch):
    monkeypatch.setattr(semantic_batch, "MAX_MASK_PAIRS", 10)
    assert _batch([5, 1]).pair_first.numel() == 10  # 5 masks: 10 pairs, at the bound
    with pytest.raises(InputError, match=r"views 0\.\.1: 13 pairs"):
        _batch([5, 3])
