"""The batched stage-2 loss equals the per-view losses of csgs_codec.train.losses, and the
batch's matrices equal coalescing their triplets."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.train import semantic_batch
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


def _coalesced_csr_pair(row, col, data, shape):
    """The reference: (matrix, transpose) by coalescing the triplets (duplicates summed) and
    converting, as batches were built before they were built from sorted triplets."""
    indices = torch.stack([row, col])
    matrix = torch.sparse_coo_tensor(indices, data, shape).coalesce().to_sparse_csr()
    transpose = torch.sparse_coo_tensor(indices.flip(0), data, shape[::-1])
    return matrix, transpose.coalesce().to_sparse_csr()


def _reference_batch_matrices(views, group_count, ignore_id):
    """The batch's four matrices built the reference way from the views."""
    rows, cols, values, mask_rows = [], [], [], []
    row_offset = mask_offset = 0
    for view in views:
        flat = view.mask.reshape(-1)
        kept = torch.ones_like(flat, dtype=torch.bool) if ignore_id is None else flat != ignore_id
        _, index = torch.unique(flat[kept], return_inverse=True)
        mask_of_pixel = torch.full(flat.shape, -1, dtype=torch.int64)
        mask_of_pixel[kept] = index
        coo = view.contributions.coalesce()
        pixel, group = coo.indices()
        covered = torch.zeros(flat.shape, dtype=torch.bool)
        covered[pixel] = True
        used = covered & (mask_of_pixel >= 0)
        row_of_pixel = torch.full(flat.shape, -1, dtype=torch.int64)
        row_of_pixel[used] = torch.arange(int(used.sum())) + row_offset
        keep = row_of_pixel[pixel] >= 0
        rows.append(row_of_pixel[pixel][keep])
        cols.append(group[keep])
        values.append(coo.values()[keep])
        mask_rows.append(mask_of_pixel[pixel][keep] + mask_offset)
        row_offset += int(used.sum())
        mask_offset += int(index.max()) + 1
    row, col, data = torch.cat(rows), torch.cat(cols), torch.cat(values)
    return (_coalesced_csr_pair(row, col, data, (row_offset, group_count))
            + _coalesced_csr_pair(torch.cat(mask_rows), col, data, (mask_offset, group_count)))


def _same_csr(a, b):
    return (torch.equal(a.crow_indices(), b.crow_indices())
            and torch.equal(a.col_indices(), b.col_indices())
            and torch.equal(a.values(), b.values()) and a.shape == b.shape)


@pytest.mark.parametrize("ignore_id", [None, 0])
def test_batch_matrices_equal_coalescing_the_triplets(prepared, ignore_id, monkeypatch):
    views, groups = prepared
    # A small chunk, so the transpose's counting sort crosses many chunk boundaries.
    monkeypatch.setattr(semantic_batch, "TRANSPOSE_CHUNK", 37)
    batch = ViewBatch.from_views([v.contributions for v in views], [v.mask for v in views],
                                 groups, ignore_id=ignore_id)
    matrix, transpose, mask_matrix, mask_transpose = _reference_batch_matrices(
        views, groups, ignore_id)
    assert _same_csr(batch.matrix, matrix) and _same_csr(batch.transpose, transpose)
    # The mask sums are per view; torch's coalescing of all views at once may add a mask's
    # entries in another order (equal on the 24-view plant capture, one float32 rounding
    # apart on these tiny views).
    for built, reference in ((batch.mask_matrix, mask_matrix),
                             (batch.mask_transpose, mask_transpose)):
        assert torch.equal(built.crow_indices(), reference.crow_indices())
        assert torch.equal(built.col_indices(), reference.col_indices())
        torch.testing.assert_close(built.values(), reference.values(), rtol=1e-6, atol=1e-6)


def test_a_released_batch_equals_a_kept_one_and_empties_the_list(prepared):
    views, groups = prepared
    kept = ViewBatch.from_views([v.contributions for v in views], [v.mask for v in views],
                                groups)
    handed = [v.contributions for v in views]
    released = ViewBatch.from_views(handed, [v.mask for v in views], groups, release=True)
    assert handed == [None] * len(views)
    for name in ("matrix", "transpose", "mask_matrix", "mask_transpose"):
        assert _same_csr(getattr(kept, name), getattr(released, name))
    for name in ("mask_index", "mask_ids", "sizes", "mask_view", "pair_first"):
        assert torch.equal(getattr(kept, name), getattr(released, name))
