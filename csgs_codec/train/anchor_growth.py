"""Anchor growing and pruning (Scaffold-GS), and view-frequency pruning (CSGaussian).

Between rounds, :class:`GrowthStats` accumulates for every slot (anchor, offset) the
screen-space gradient of its Gaussian's centre, and for every anchor its opacity and the views
that saw it. A round then

* **grows**: slots whose mean screen-space gradient is in the top ``grow_fraction`` of the slots
  that were seen spawn an anchor at their centre's voxel when that voxel holds none yet (the new
  anchor starts from its parent's feature). Stage 1 puts its initial anchors on every second
  cell of the grid, so growth adds anchors at half their spacing, as Scaffold-GS's finer
  growth levels do, and new anchors must pass the view-frequency rule too. Scaffold-GS
  compares the gradient with an absolute threshold; its scale depends on the loss
  normalisation and the image size, so a quantile is used instead;
* **prunes**: anchors seen in at least one view whose mean summed opacity per view is below
  ``min_opacity`` (Scaffold-GS's rule), unless that would leave none.

:func:`view_counts` counts the training views whose frustum holds each anchor; stage 1 drops
anchors seen from fewer than ``min_views`` views (they are fitted to too few images to
generalise and cost bits all the same).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from csgs_codec.model.scaffold import NeuralGaussians
from csgs_codec.scene.camera import Camera
from csgs_codec.train.anchor_model import AnchorModel

#: Where :class:`GrowthStats` accumulate, whatever the training device.
STATS_DEVICE = torch.device("cpu")  # cpu: CUDA's index_add_ is not deterministic


def view_counts(positions: np.ndarray, cameras: list[Camera]) -> np.ndarray:
    """(M,) int64 number of ``cameras`` whose image holds each (M, 3) position (in front of
    the near plane and inside the image)."""
    points = np.asarray(positions, np.float64)
    counts = np.zeros(len(points), np.int64)
    homogeneous = np.concatenate([points, np.ones((len(points), 1))], axis=1)
    for camera in cameras:
        cam = homogeneous @ camera.world_to_camera.T
        z = cam[:, 2]
        ahead = z > camera.near_plane
        safe_z = np.where(ahead, z, 1.0)
        u = camera.fx * cam[:, 0] / safe_z + camera.cx
        v = camera.fy * cam[:, 1] / safe_z + camera.cy
        counts += ahead & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    return counts


@dataclass
class GrowthStats:
    """Accumulators of one growth interval (module notes), float64/int64 on
    :data:`STATS_DEVICE` (the CPU) whatever the training device (CUDA's index_add_ is not
    deterministic).

    Attributes:
        grad_sum: (M * K,) summed screen-space gradient norms of each slot's centre, in loss
            units per pixel, over the views where its anchor was seen.
        grad_count: (M * K,) number of such views.
        opacity_sum: (M,) summed opacity of each anchor's kept Gaussians over the views.
        visits: (M,) number of views whose image holds the anchor.
    """

    grad_sum: torch.Tensor
    grad_count: torch.Tensor
    opacity_sum: torch.Tensor
    visits: torch.Tensor

    @classmethod
    def empty(cls, anchors: int, n_offsets: int) -> GrowthStats:
        """Zeroed accumulators for ``anchors`` anchors of ``n_offsets`` slots."""
        slots = anchors * n_offsets
        return cls(torch.zeros(slots, dtype=torch.float64, device=STATS_DEVICE),
                   torch.zeros(slots, dtype=torch.int64, device=STATS_DEVICE),
                   torch.zeros(anchors, dtype=torch.float64, device=STATS_DEVICE),
                   torch.zeros(anchors, dtype=torch.int64, device=STATS_DEVICE))

    def record(self, gaussians: NeuralGaussians, camera: Camera, n_offsets: int,
               seen: np.ndarray) -> None:
        """Add one view: ``gaussians.positions.grad`` must hold dL/d(centre) (N, 3);
        ``seen`` (M,) bool anchors inside the view. Spawned with every slot or only the kept
        ones, the same view adds the same statistics."""
        with torch.no_grad():
            device = self.visits.device
            grad = gaussians.positions.grad
            anchors = gaussians.anchor_index.to(device)
            slots = anchors * n_offsets + gaussians.offset_index.to(device)
            visible = torch.as_tensor(np.asarray(seen, bool), device=device)[anchors]
            if gaussians.all_slots:  # only the slots that produced a Gaussian count
                visible &= gaussians.keep.to(device)
            if grad is not None and bool(visible.any()):
                positions = gaussians.positions.detach().to(device).double()
                w2c = torch.as_tensor(camera.world_to_camera, device=device)
                depth = (positions @ w2c[:3, :3].T + w2c[:3, 3])[:, 2].abs()
                # |dL/d pixel| ~ |dL/d centre| * z / f for motion across the image plane.
                pixel_grad = grad.detach().to(device).double().norm(dim=1) * depth / camera.fx
                self.grad_sum.index_add_(0, slots[visible], pixel_grad[visible])
                self.grad_count.index_add_(0, slots[visible],
                                           torch.ones(int(visible.sum()), dtype=torch.int64,
                                                      device=device))
            self.opacity_sum.index_add_(0, anchors,
                                        gaussians.opacities.detach().to(device).double())
            self.visits += torch.as_tensor(np.asarray(seen).astype(np.int64), device=device)


def grow_and_prune(model: AnchorModel, stats: GrowthStats, *, grow_fraction: float,
                   min_opacity: float, max_anchors: int,
                   accept: Callable[[np.ndarray], np.ndarray] | None = None
                   ) -> tuple[int, int]:
    """One round (module notes) on ``model``, in place; returns (grown, pruned) counts.

    ``accept`` maps candidate anchor positions (A, 3) to an (A,) bool mask of those that may
    be added (stage 1 passes the view-frequency rule). The caller learns which rows survived
    from :func:`prune_mask` (computed before the round) and that grown anchors are appended
    after them."""
    m, k = model.count, model.n_offsets
    seen_slots = stats.grad_count > 0
    grown_cells = np.zeros((0, 3), np.int64)
    parents = torch.zeros(0, dtype=torch.int64, device=stats.grad_count.device)
    room = max_anchors - m
    if bool(seen_slots.any()) and room > 0 and grow_fraction > 0:
        mean_grad = torch.where(seen_slots, stats.grad_sum / stats.grad_count.clamp_min(1), 0.0)
        # The (1 - grow_fraction) quantile by sorting (torch.quantile stops at 2^24 values).
        ranked = torch.sort(mean_grad[seen_slots]).values
        threshold = ranked[min(int((1.0 - grow_fraction) * len(ranked)), len(ranked) - 1)]
        candidates = torch.nonzero(seen_slots & (mean_grad >= threshold) & (mean_grad > 0))
        candidates = candidates.reshape(-1)
        # Strongest first, so a limited budget goes to the largest gradients.
        candidates = candidates[torch.argsort(mean_grad[candidates], descending=True,
                                              stable=True)]
        centres = model.slot_positions().reshape(m * k, 3)[candidates.to(
            model.positions.device)].cpu().numpy()
        cells = model.grid.cells_of(centres)
        if accept is not None and len(cells):
            allowed = np.asarray(accept(model.grid.centres(cells)), bool)
            cells = cells[allowed]
            candidates = candidates[torch.as_tensor(allowed, device=candidates.device)]
        existing = {tuple(c) for c in model.cells.cpu().numpy().tolist()}
        chosen, chosen_parents = [], []
        for cell, slot in zip(cells.tolist(), candidates.tolist()):
            key = tuple(cell)
            if key in existing:
                continue
            existing.add(key)
            chosen.append(cell)
            chosen_parents.append(slot // k)
            if len(chosen) >= room:
                break
        if chosen:
            grown_cells = np.asarray(chosen, np.int64)
            parents = torch.as_tensor(chosen_parents, dtype=torch.int64,
                                      device=candidates.device)
    prune = prune_mask(stats, min_opacity)
    pruned = int(prune.sum())
    if pruned or len(grown_cells):
        model.resize(~prune, grown_cells, parents)
    return len(grown_cells), pruned


def prune_mask(stats: GrowthStats, min_opacity: float) -> torch.Tensor:
    """(M,) bool anchors :func:`grow_and_prune` removes: seen, but with a mean summed opacity
    per view below ``min_opacity`` (none when that would remove every anchor)."""
    mean_opacity = stats.opacity_sum / stats.visits.clamp_min(1)
    prune = (stats.visits > 0) & (mean_opacity < min_opacity)
    return torch.zeros_like(prune) if bool(prune.all()) else prune
