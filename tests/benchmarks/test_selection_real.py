"""benchmarks/selection_real.py's protocol on a tiny labelled synthetic scene: the document's
fields, IoUs in [0, 1], the label reader and the mask perturbations."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from benchmarks import selection_real
from benchmarks.selection_real import (
    Protocol,
    build_document,
    jitter_boundaries,
    merge_objects,
    read_labels,
)
from csgs_codec.semantic.synthetic import labelled_blob_scene


@pytest.fixture(scope="module")
def doc():
    scene = labelled_blob_scene(n_objects=4, per_object=40, seed=3)
    labels = scene.labels.astype(np.int32)  # object 0 plays the unlabelled Gaussians
    scene.labels = None
    protocol = Protocol(views=8, width=64, height=48, stage2_iterations=3,
                        stage3_iterations=2, qualities=(5,), noisy_masks=True, merged=True)
    return build_document(scene, labels, protocol, scene_name="blobs", notes="test")


def test_document_has_every_variant_coding_and_mode(doc):
    assert doc["schema"] == "csgs-bench/1" and doc["benchmark"] == "selection_real"
    assert doc["views"]["train"] == 6 and doc["views"]["held_out"] == 2
    assert doc["clicks"]["count"] > 0 and doc["categories"] == 3
    seen = {(r["masks"], r["variant"], r["coding"]) for r in doc["results"]}
    for masks in ("clean", "noisy", "merged"):
        for variant in ("stage2", "stage2+3"):
            assert {(masks, variant, "uncompressed"), (masks, variant, "quality 5")} <= seen
    for variant in ("onehot", "labels"):
        assert ("clean", variant, "quality 5") in seen
    for stage in ("contribution_matrices", "stage2", "stage3"):
        assert doc["seconds"]["clean"][stage] >= 0
    assert "contribution_matrices" not in doc["seconds"]["noisy"]  # computed once


def test_ious_and_sizes_are_in_range(doc):
    for row in doc["results"]:
        modes = {"labels": ("label", "instance"),
                 "segment": ("instance",)}.get(row["variant"], ("cosine", "cluster"))
        assert set(row["selection"]) == set(modes)
        for scores in row["selection"].values():
            assert 0.0 <= scores["miou_3d"] <= 1.0 and 0.0 <= scores["miou_2d"] <= 1.0
            assert scores["clicks"] == doc["clicks"]["count"]
            assert all(0.0 <= v <= 1.0 for v in scores["miou_3d_per_category"].values())
        if row["quality"] is not None:
            assert 0 < row["semantic_bytes"] < row["file_bytes"]
            assert 0 < row["semantic_share_percent"] < 100
    # Labels decode exactly and decide the ground truth: clicked uncompressed they score 1.
    labels = next(r for r in doc["results"]
                  if r["variant"] == "labels" and r["quality"] is None)["selection"]["label"]
    assert labels["miou_3d"] == 1.0 and labels["miou_2d"] == 1.0


def test_label_file_is_read_from_the_segments_ai_layout(tmp_path):
    path = tmp_path / "labels.json"
    path.write_text(json.dumps({"dataset": {
        "task_type": "pointcloud-segmentation",
        "task_attributes": {"categories": [{"id": 1}, {"id": 2}, {"id": 3}]},
        "samples": [{"name": "s.ply", "labels": {"ground-truth": {"attributes": {
            "point_annotations": [0.0, 1.0, 1.0, 2.0]}}}}]}}))
    labels, facts = read_labels(path)
    assert labels.tolist() == [0, 1, 1, 2] and labels.dtype == np.int32
    assert facts["categories_declared"] == 3 and facts["categories_used"] == 2
    assert facts["gaussians_per_label"] == {"0": 1, "1": 2, "2": 1}


def test_mask_perturbations_touch_boundaries_and_merge_two_objects():
    mask = np.zeros((20, 20), np.int32)
    mask[5:15, 5:15] = 1
    mask[5:15, 15:] = 2
    noisy = jitter_boundaries(mask, np.random.default_rng(0))
    assert np.array_equal(noisy[9:11, 9:11], mask[9:11, 9:11])  # interior kept
    assert np.count_nonzero(noisy != mask) > 0
    merged, merges = merge_objects([mask] * 10, 2, np.random.default_rng(0), 0.2)
    assert len(merges) == 2
    assert sum(len(np.unique(m)) == 2 for m in merged) == 2


def test_missing_shared_data_exits_2(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(selection_real, "REAL", tmp_path / "absent")
    monkeypatch.setattr(sys, "argv", ["selection_real.py"])
    assert selection_real.main() == 2
    assert "absent" in capsys.readouterr().err
