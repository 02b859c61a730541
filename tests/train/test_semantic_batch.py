"""The batched stage-2 loss equals the per-view losses of csgs_codec.train.losses."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.train.losses import inter_mask_contrastive_loss, intra_mask_smoothing_loss
from csgs_codec.train.semantic_batch import ViewBatch
from csgs_codec.train.semantic_stage import prepare_semantic_views
from csgs_codec.train.synthetic import make_synthetic_dataset


@pytest.fixture(scope="module")
def prepared():
    dataset = make_synthetic_dataset(5, objects=3, gaussians_per_object=40, views=3, width=32,
                                     height=24)
    views = prepare_semantic_views(dataset.scene, dataset.views)
    return views, len(dataset.scene)


def _per_view_loss(views, values, margin, weight, ignore_id=None):
    total = torch.zeros((), dtype=torch.float64)
    for view in views:
        rendered = torch.sparse.mm(view.contributions.to(torch.float64), values)
        total = total + intra_mask_smoothing_loss(rendered, view.mask, ignore_id)
        total = total + weight * inter_mask_contrastive_loss(rendered, view.mask, margin,
                                                             ignore_id)
    return total / len(views)


@pytest.mark.parametrize("ignore_id", [None, 0])
def test_batch_loss_and_gradient_equal_the_per_view_losses(prepared, ignore_id):
    views, groups = prepared
    rng = np.random.default_rng(3)
    start = rng.normal(scale=2.0, size=(groups, 6))
    batch = ViewBatch.from_views([v.contributions for v in views], [v.mask for v in views],
                                 groups, ignore_id=ignore_id)
    # Masks that are all background in a view still count: some pixels no group covers.
    assert batch.matrix.shape[0] < sum(v.mask.numel() for v in views)
    values = torch.tensor(start, dtype=torch.float32, requires_grad=True)
    got = batch.loss(values, 4.0, 0.7)
    got.backward()
    reference = torch.tensor(start, dtype=torch.float64, requires_grad=True)
    expected = _per_view_loss(views, reference, 4.0, 0.7, ignore_id)
    expected.backward()
    assert expected.item() > 0.1
    np.testing.assert_allclose(got.item(), expected.item(), rtol=1e-4)
    np.testing.assert_allclose(values.grad.numpy(), reference.grad.numpy(), rtol=1e-3,
                               atol=1e-5 * float(reference.grad.abs().max()))


def test_batch_rejects_a_matrix_that_does_not_match_its_mask(prepared):
    views, groups = prepared
    with pytest.raises(InputError, match="view 1"):
        ViewBatch.from_views([views[0].contributions, views[0].contributions],
                             [views[0].mask, views[1].mask[:-1]], groups)
