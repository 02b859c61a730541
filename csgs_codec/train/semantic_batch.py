"""All training views of stages 2-3 as one sparse product and one vectorised loss.

The views' contribution matrices (pixels x groups, :func:`contribution_matrix`) are stacked
into one compressed-row matrix A over the pixels that belong to some mask and that some group
covers, with its transpose kept beside it, so a training step is two sparse products (A v
forward, A^T g backward) instead of a sparse autograd product per view. The smoothing term is
computed from per-mask moments, sum ||F_p - mu||^2 = sum ||F_p||^2 - |P| ||mu||^2, so pixels
no group covers (F_p = 0) count only in |P| and need no row, and the mask sums come from a
second sparse matrix S A (masks x groups) built once. The semantic loss of
:mod:`csgs_codec.train.losses` is evaluated for every view at once: masks are numbered across
views, the smoothing term is averaged over each view's masks, the contrastive term over each
view's pairs of masks (masks of different views are never compared: their ids are unrelated),
and the sum of the two is averaged over views, exactly as the per-view functions would give.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import torch

from csgs_codec.errors import InputError
from csgs_codec.train.heap import release_freed_memory

#: Most mask ids one view may hold: the contrastive term compares every pair of a view's
#: masks, so its memory grows as the square (12,695 ids in one view took 6.9 GB). SAM gives
#: tens to hundreds per image, the built-in segmenter at most about 1,000.
MAX_MASKS_PER_VIEW = 2048
#: Most same-view mask pairs over all views (each costs about 100 bytes per training step).
MAX_MASK_PAIRS = 1 << 25


class _SparseProduct(torch.autograd.Function):
    """A @ values with the gradient A^T @ grad from a transpose built once."""

    @staticmethod
    def forward(ctx, values: torch.Tensor, matrix: torch.Tensor,
                transpose: torch.Tensor) -> torch.Tensor:
        ctx.transpose = transpose
        return matrix @ values

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        return ctx.transpose @ grad.contiguous(), None, None


@dataclass
class ViewBatch:
    """The masked pixels of every view, their contribution rows and their mask structure.

    Attributes:
        matrix: (R, G) float32 sparse CSR, one row per masked pixel of every view that some
            group covers.
        transpose: (G, R) float32 sparse CSR, ``matrix`` transposed.
        mask_matrix: (M, G) float32 sparse CSR, the rows of ``matrix`` summed per mask.
        mask_transpose: (G, M) float32 sparse CSR, ``mask_matrix`` transposed.
        mask_index: [R] int64 mask of each row, masks numbered across views.
        mask_ids: [M] int64 each mask's id in its view's mask image.
        sizes: [M] float32 pixel count of each mask (covered or not).
        mask_view: [M] int64 view of each mask.
        masks_per_view: [V] float32 masks of each view.
        pair_first, pair_second: [P] int64 the two masks of each same-view pair.
        pair_view: [P] int64 view of each pair.
        pairs_per_view: [V] float32 pairs of each view.
        view_count: V.
    """

    matrix: torch.Tensor
    transpose: torch.Tensor
    mask_matrix: torch.Tensor
    mask_transpose: torch.Tensor
    mask_index: torch.Tensor
    mask_ids: torch.Tensor
    sizes: torch.Tensor
    mask_view: torch.Tensor
    masks_per_view: torch.Tensor
    pair_first: torch.Tensor
    pair_second: torch.Tensor
    pair_view: torch.Tensor
    pairs_per_view: torch.Tensor
    view_count: int

    @classmethod
    def from_views(cls, contributions: list[torch.Tensor], masks: list[torch.Tensor],
                   group_count: int, *, ignore_id: int | None = None,
                   device: str | torch.device = "cpu", release: bool = False) -> ViewBatch:
        """Stack views: ``contributions[v]`` (H_v * W_v, G) sparse, ``masks[v]`` (H_v, W_v)
        integer ids (``ignore_id`` pixels belong to no mask). With ``release``, each
        ``contributions[v]`` is set to None once read, so a caller that keeps no other
        reference holds each view's matrix or its rows of the batch, never both.

        Raises:
            InputError: a matrix that does not match its mask or G.
        """
        mask_parts, sizes, mask_view, ids = [], [], [], []
        # Upper bound of the rows' entries, filled in place (no per-view copies to join).
        capacity = sum(int(matrix.coalesce()._nnz()) if matrix.layout == torch.sparse_coo
                       else 0 for matrix in contributions)
        row = torch.empty(capacity, dtype=torch.int64, device=device)
        col = torch.empty(capacity, dtype=torch.int64, device=device)
        data = torch.empty(capacity, dtype=torch.float32, device=device)
        filled = 0
        mask_rows, mask_cols, mask_values = [], [], []
        masks_per_view, firsts, seconds, pair_views, pairs_per_view = [], [], [], [], []
        row_offset = mask_offset = total_pairs = 0
        for v, mask in enumerate(masks):
            matrix = contributions[v]
            if release:
                contributions[v] = None
            pixels = mask.shape[0] * mask.shape[1] if mask.ndim == 2 else -1
            if tuple(matrix.shape) != (pixels, group_count):
                raise InputError(f"view {v}: contributions {tuple(matrix.shape)} do not match "
                                 f"mask {tuple(mask.shape)} and {group_count} groups",
                                 index=v, property="contributions")
            flat = mask.reshape(-1).to(device)
            kept = (torch.ones_like(flat, dtype=torch.bool) if ignore_id is None
                    else flat != ignore_id)
            view_ids, index = torch.unique(flat[kept], return_inverse=True)
            ids.append(view_ids.to(torch.int64))
            count = int(index.max()) + 1 if index.numel() else 0
            if count > MAX_MASKS_PER_VIEW:
                raise InputError(f"view {v}: {count:,} mask ids, more than the "
                                 f"{MAX_MASKS_PER_VIEW:,} a view may hold (every pair of a "
                                 "view's masks is compared)", index=v, property="masks")
            total_pairs += count * (count - 1) // 2
            if total_pairs > MAX_MASK_PAIRS:
                raise InputError(f"views 0..{v}: {total_pairs:,} pairs of same-view masks, "
                                 f"more than {MAX_MASK_PAIRS:,}: use fewer views or fewer "
                                 "masks per view", property="masks")
            mask_of_pixel = torch.full((pixels,), -1, dtype=torch.int64, device=device)
            mask_of_pixel[kept] = index
            coo = matrix.to(device).coalesce()
            del matrix
            pixel, group = coo.indices()
            covered = torch.zeros(pixels, dtype=torch.bool, device=device)
            covered[pixel] = True
            used = covered & (mask_of_pixel >= 0)
            # New row number of each used pixel; -1 for the others.
            row_of_pixel = torch.full((pixels,), -1, dtype=torch.int64, device=device)
            row_of_pixel[used] = torch.arange(int(used.sum()), device=device) + row_offset
            new_row = row_of_pixel[pixel]
            keep = new_row >= 0
            end = filled + int(keep.sum())
            row[filled:end] = new_row[keep]
            col[filled:end] = group[keep]
            data[filled:end] = coo.values()[keep].to(torch.float32)
            mask_parts.append(mask_of_pixel[used] + mask_offset)
            # The view's rows summed per mask (masks of different views share no entry; one
            # view at a time bounds the memory, and equals coalescing all views at once
            # except for the order torch adds a mask's entries in on tiny views).
            summed = torch.sparse_coo_tensor(
                torch.stack([mask_of_pixel[pixel[keep]], group[keep]]), data[filled:end],
                (max(count, 1), group_count), check_invariants=False,
                device=device).coalesce()
            filled = end
            del coo, pixel, group, new_row, keep
            mask_rows.append(summed.indices()[0] + mask_offset)
            mask_cols.append(summed.indices()[1])
            mask_values.append(summed.values())
            sizes.append(torch.bincount(index, minlength=count).to(torch.float32))
            mask_view.append(torch.full((count,), v, dtype=torch.int64, device=device))
            masks_per_view.append(count)
            first, second = torch.triu_indices(count, count, offset=1, device=device)
            firsts.append(first + mask_offset)
            seconds.append(second + mask_offset)
            pair_views.append(torch.full((first.numel(),), v, dtype=torch.int64, device=device))
            pairs_per_view.append(first.numel())
            row_offset += int(used.sum())
            mask_offset += count
        if not masks:
            raise InputError("stage 2 needs at least one view", property="views")
        row_mask = torch.cat(mask_parts)
        del mask_parts
        if release:
            release_freed_memory()  # the views' matrices, before the transposes are built
        row, col, data = row[:filled], col[:filled], data[:filled]
        if filled < capacity // 2:  # many ignored pixels: drop the unused room
            row, col, data = row.clone(), col.clone(), data.clone()
        # Rows grow with the views and with the pixels of a (coalesced) view, so the triplets
        # are already in row-major order without repeats: no coalescing needed for A.
        matrix, transpose = _sorted_csr_pair(row, col, data, (row_offset, group_count))
        del row, col, data
        mask_matrix, mask_transpose = _sorted_csr_pair(
            torch.cat(mask_rows), torch.cat(mask_cols), torch.cat(mask_values),
            (mask_offset, group_count))
        return cls(matrix, transpose, mask_matrix, mask_transpose, row_mask, torch.cat(ids),
                   torch.cat(sizes), torch.cat(mask_view),
                   torch.tensor(masks_per_view, dtype=torch.float32, device=device),
                   torch.cat(firsts), torch.cat(seconds), torch.cat(pair_views),
                   torch.tensor(pairs_per_view, dtype=torch.float32, device=device),
                   len(masks))

    @property
    def mask_count(self) -> int:
        """M, the masks of all views."""
        return int(self.sizes.shape[0])

    def render(self, values: torch.Tensor) -> torch.Tensor:
        """[R, D] rendered features of the masked pixels from per-group values [G, D]
        (differentiable in ``values``)."""
        return _SparseProduct.apply(values.contiguous(), self.matrix, self.transpose)

    def mask_means(self, values: torch.Tensor) -> torch.Tensor:
        """[M, D] mean rendered feature of each mask from per-group values [G, D]."""
        sums = _SparseProduct.apply(values.contiguous(), self.mask_matrix, self.mask_transpose)
        return sums / self.sizes[:, None]

    def loss(self, values: torch.Tensor, margin: float, contrastive_weight: float
             ) -> torch.Tensor:
        """Mean over views of L_s + contrastive_weight * L_c (module notes); scalar.

        Args:
            values: [G, D] per-group values (the features as rendered).
            margin: the contrastive margin (> 0), feature units.
            contrastive_weight: lambda_c.
        """
        if not margin > 0:
            raise InputError(f"margin must be positive, got {margin}", property="margin")
        dtype, device = values.dtype, values.device
        means = self.mask_means(values)
        rendered = self.render(values)
        second = torch.zeros(self.mask_count, dtype=dtype, device=device).index_add(
            0, self.mask_index, torch.sum(rendered * rendered, dim=1))
        per_mask = second / self.sizes - torch.sum(means * means, dim=1)
        smoothing = torch.zeros(self.view_count, dtype=dtype, device=device).index_add(
            0, self.mask_view, per_mask) / self.masks_per_view.clamp(min=1)
        gap = means[self.pair_first] - means[self.pair_second]
        distance = torch.sqrt(torch.sum(gap * gap, dim=1) + 1e-12)
        penalty = torch.relu(margin - distance) ** 2
        contrast = torch.zeros(self.view_count, dtype=dtype, device=device).index_add(
            0, self.pair_view, penalty) / self.pairs_per_view.clamp(min=1)
        return torch.sum(smoothing + contrastive_weight * contrast) / self.view_count


def _sorted_csr_pair(row: torch.Tensor, col: torch.Tensor, data: torch.Tensor,
                     shape: tuple[int, int]) -> tuple[torch.Tensor, torch.Tensor]:
    """(matrix, its transpose) as CSR from COO triplets already in row-major order without
    repeated (row, col) pairs: the tensors that coalescing the triplets and converting them
    gives (tests/train/test_semantic_batch.py checks them equal), without the two coalescing
    sorts and their copies of the indices (the largest memory of a batch)."""
    device = data.device
    crow = torch.zeros(shape[0] + 1, dtype=torch.int64, device=device)
    crow[1:] = torch.cumsum(torch.bincount(row, minlength=shape[0]), 0)
    t_crow = torch.zeros(shape[1] + 1, dtype=torch.int64, device=device)
    t_crow[1:] = torch.cumsum(torch.bincount(col, minlength=shape[1]), 0)
    if device.type == "cpu":
        t_col, t_data = _transposed_entries(row, col, data, t_crow)
    else:
        order = torch.argsort(col, stable=True)
        t_col, t_data = row[order], data[order]
    with warnings.catch_warnings():  # torch calls its CSR support "beta" on every conversion
        warnings.filterwarnings("ignore", message=".*Sparse CSR tensor support.*")
        matrix = torch.sparse_csr_tensor(crow, col, data, shape, check_invariants=False,
                                         device=device)
        transpose = torch.sparse_csr_tensor(t_crow, t_col, t_data, shape[::-1],
                                            check_invariants=False, device=device)
    return matrix, transpose


#: Entries placed at a time by :func:`_transposed_entries` (bounds its temporary memory).
TRANSPOSE_CHUNK = 1 << 20


def _transposed_entries(row: torch.Tensor, col: torch.Tensor, data: torch.Tensor,
                        t_crow: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(column indices, values) of the transpose of row-major CPU triplets: a counting sort
    by ``col`` that keeps row order within a column (the stable order), placed a chunk at a
    time so that no full-length permutation is ever held."""
    rows, cols, values = row.numpy(), col.numpy(), data.numpy()
    t_col = np.empty_like(rows)
    t_data = np.empty_like(values)
    placed = t_crow[:-1].numpy().copy()  # next free slot of each column
    for start in range(0, len(cols), TRANSPOSE_CHUNK):
        keys = cols[start:start + TRANSPOSE_CHUNK]
        order = np.argsort(keys, kind="stable")
        ordered = keys[order]
        run_start = np.ones(len(keys), bool)
        run_start[1:] = ordered[1:] != ordered[:-1]
        starts = np.flatnonzero(run_start)
        rank = np.empty(len(keys), np.int64)
        rank[order] = np.arange(len(keys)) - np.repeat(starts, np.diff(np.r_[starts,
                                                                               len(keys)]))
        slot = placed[keys] + rank
        t_col[slot] = rows[start:start + TRANSPOSE_CHUNK]
        t_data[slot] = values[start:start + TRANSPOSE_CHUNK]
        placed += np.bincount(keys, minlength=len(placed))
    return (torch.as_tensor(t_col, device=row.device),
            torch.as_tensor(t_data, device=row.device))
