"""Stage 2 on fixed geometry: contribution matrices render features; training separates masks."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.entropy.residual import encode_symbols
from csgs_codec.entropy.table_choice import best_table
from csgs_codec.errors import InputError
from csgs_codec.render.rasterizer import render
from csgs_codec.train import semantic_stage
from csgs_codec.train.semantic_stage import (
    SemanticView,
    contribution_matrix,
    prepare_semantic_views,
    train_semantic_features,
)
from csgs_codec.train.synthetic import make_synthetic_dataset

PER_OBJECT = 50


@pytest.fixture(scope="module")
def dataset():
    return make_synthetic_dataset(11, objects=3, gaussians_per_object=PER_OBJECT, views=3,
                                  width=32, height=24)


@pytest.fixture(scope="module")
def trained(dataset):
    views = prepare_semantic_views(dataset.scene, dataset.views)
    return views, train_semantic_features(views, len(dataset.scene), iterations=40, seed=4)


def test_contribution_matrix_reproduces_the_rendered_feature_map(dataset, monkeypatch):
    monkeypatch.setattr(semantic_stage, "MIN_CONTRIBUTION", 0.0)
    camera = dataset.views[0].camera
    features = np.random.default_rng(0).normal(size=(len(dataset.scene), 4)).astype(np.float32)
    expected = render(dataset.scene, camera, features=features).features
    matrix = contribution_matrix(dataset.scene, camera)
    got = torch.sparse.mm(matrix, torch.from_numpy(features)).numpy()
    np.testing.assert_allclose(got.reshape(expected.shape), expected, atol=1e-5)


def test_grouped_matrix_sums_the_columns_of_its_gaussians(dataset, monkeypatch):
    monkeypatch.setattr(semantic_stage, "MIN_CONTRIBUTION", 0.0)
    camera = dataset.views[1].camera
    groups = np.arange(len(dataset.scene)) // 5
    per_gaussian = contribution_matrix(dataset.scene, camera).to_dense()
    grouped = contribution_matrix(dataset.scene, camera, groups).to_dense()
    summed = torch.zeros_like(grouped).index_add(1, torch.from_numpy(groups), per_gaussian)
    torch.testing.assert_close(grouped, summed, atol=1e-6, rtol=1e-5)


def test_training_lowers_the_loss_and_separates_the_objects(dataset, trained):
    views, result = trained
    assert result.losses[-1] < 0.2 * result.losses[0]
    visible = sum(v.contributions.to_dense().sum(0) for v in views).numpy() > 0.5
    labels = dataset.scene.labels
    codes = np.rint(result.features)  # quantized with Q = 1, as the codec will
    means = np.stack([codes[(labels == k) & visible].mean(axis=0) for k in (1, 2, 3)])
    nearest = np.argmin(((codes[:, None] - means[None]) ** 2).sum(axis=2), axis=1) + 1
    assert np.mean(nearest[visible] == labels[visible]) > 0.9
    gaps = [np.linalg.norm(means[a] - means[b]) for a, b in ((0, 1), (0, 2), (1, 2))]
    assert min(gaps) > 1.5


def test_training_is_reproducible_from_the_seed(dataset, trained):
    views, _ = trained
    first = train_semantic_features(views, len(dataset.scene), iterations=5, seed=4)
    again = train_semantic_features(views, len(dataset.scene), iterations=5, seed=4)
    assert again.features.tobytes() == first.features.tobytes()
    assert again.losses.tobytes() == first.losses.tobytes()
    other = train_semantic_features(views, len(dataset.scene), iterations=5, seed=5)
    assert not np.array_equal(other.features, first.features)


def test_groups_weighted_zero_by_quality_keep_their_initial_feature(dataset, trained):
    views, _ = trained
    n = len(dataset.scene)
    steps = np.ones(n, np.float32)
    steps[:PER_OBJECT] = 2.0  # object 1: norm 1, weight 1 - 1 = 0
    start = train_semantic_features(views, n, iterations=0, seed=4, color_steps=steps)
    after = train_semantic_features(views, n, iterations=10, seed=4, color_steps=steps)
    np.testing.assert_array_equal(after.features[:PER_OBJECT], start.features[:PER_OBJECT])
    assert not np.array_equal(after.features[PER_OBJECT:], start.features[PER_OBJECT:])


def coded_bits(codes: np.ndarray) -> int:
    """Bits of integer features (G, D) coded per channel around the channel's median with the
    best frozen table, as the residual coder writes them."""
    total = 0
    for column in codes.T.astype(np.int64):
        residuals = column - int(np.median(column))
        table = np.full(residuals.size, best_table(residuals))
        total += 8 * len(encode_symbols(residuals, table))
    return total


def test_stage_three_rate_term_lowers_the_coded_size_of_the_features(dataset, trained):
    views, _ = trained
    n = len(dataset.scene)
    plain = train_semantic_features(views, n, iterations=40, seed=4, rate_weight=0.0)
    costly = train_semantic_features(views, n, iterations=40, seed=4, rate_weight=0.5)
    assert np.all(plain.bits == 0) and plain.rate_model is None
    assert np.all(costly.bits > 0) and costly.rate_model is not None
    plain_size = coded_bits(np.rint(plain.features))
    costly_size = coded_bits(np.rint(costly.features))
    assert costly_size < 0.9 * plain_size
    # The estimate tracks the coded size of the rounded features.
    assert costly.bits[-1] * n == pytest.approx(costly_size, rel=0.15)


def test_rate_term_needs_a_quantization_step(dataset, trained):
    views, _ = trained
    with pytest.raises(InputError, match="noise_step"):
        train_semantic_features(views, len(dataset.scene), iterations=1, rate_weight=0.1,
                                noise_step=0.0)


def test_mismatched_views_and_missing_masks_are_rejected(dataset, trained):
    views, _ = trained
    with pytest.raises(InputError, match="contributions"):
        train_semantic_features(views, len(dataset.scene) + 1, iterations=1)
    bad = SemanticView(views[0].contributions, views[0].mask[:, :-1])
    with pytest.raises(InputError, match="contributions"):
        train_semantic_features([bad], len(dataset.scene), iterations=1)
    with pytest.raises(InputError, match="at least one view"):
        train_semantic_features([], len(dataset.scene))
    unmasked = dataset.views[0]
    unmasked = type(unmasked)(unmasked.image, unmasked.camera, None, "v")
    with pytest.raises(InputError, match="instance mask"):
        prepare_semantic_views(dataset.scene, [unmasked])
    with pytest.raises(InputError, match="groups"):
        contribution_matrix(dataset.scene, unmasked.camera, np.zeros(3, np.int64))


@pytest.mark.slow
def test_quantized_features_give_click_selection_miou_above_0_9(tmp_path):
    """Files to features: write a synthetic dataset, load it back, train stage 2, round the
    features (Q = 1) and click each object's centre with the project's click selection."""
    evaluation = pytest.importorskip("csgs_codec.semantic.evaluation")
    from csgs_codec.interchange.ply_reader import read_ply
    from csgs_codec.train.datasets import load_dataset

    make_synthetic_dataset(21, objects=4, gaussians_per_object=120, views=6, width=64,
                           height=48).write(tmp_path)
    scene = read_ply(tmp_path / "scene.ply")
    views = load_dataset(tmp_path)
    prepared = prepare_semantic_views(scene, views)
    result = train_semantic_features(prepared, len(scene), iterations=150, seed=0)
    scene.semantic = np.rint(result.features).astype(np.float32)
    scene.semantic_names = tuple(f"sem_{i}" for i in range(scene.semantic.shape[1]))
    for mode in ("cosine", "cluster"):
        scores = [evaluation.mean_iou(evaluation.click_object_ious(scene, view.camera,
                                                                   mode=mode))
                  for view in views[:3]]
        assert np.mean(scores) >= 0.9, (mode, scores)
