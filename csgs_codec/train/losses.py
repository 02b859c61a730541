"""Differentiable loss terms of the training stages (torch).

Photometric (stage 1):

* :func:`l1_loss`: mean absolute difference.
* :func:`ssim`: structural similarity with the definition of
  :func:`csgs_codec.metrics.image.ssim` (11x11 Gaussian window, sigma 1.5, C1 = 0.01^2,
  C2 = 0.03^2, "valid" windows only, averaged over windows and channels; an image smaller than
  the window is one window), computed with a separable Gaussian filter so it is differentiable.
* :func:`photometric_loss`: (1 - lambda) L1 + lambda (1 - SSIM), lambda = 0.2 as in 3DGS.

Semantic (stages 2 and 3), on a rendered feature map F (H, W, D) and an instance mask M (H, W).
Let the masks be the distinct ids m of M (less ``ignore_id``), P_m their pixels and
mu_m = mean of F over P_m:

* :func:`intra_mask_smoothing_loss`: L_s = (1 / #masks) sum_m (1 / |P_m|) sum_{p in P_m}
  ||F_p - mu_m||^2, the mean over masks of the mean squared distance to the mask's mean
  feature. It is 0 exactly when the feature is constant inside every mask.
* :func:`inter_mask_contrastive_loss`: L_c = mean over unordered pairs {a, b} of masks of
  relu(margin - ||mu_a - mu_b||)^2. It is 0 when every pair of mask means is at least
  ``margin`` apart, and its gradient pushes closer means apart. The margin must leave room
  for unit-step quantization (which moves a 6-channel feature by up to 0.5 sqrt(6) = 1.22)
  and for the spread of single Gaussians around their mask's mean under cosine click
  selection (csgs_codec.semantic.selection, threshold 0.9): on the synthetic scenes of
  :mod:`csgs_codec.train.synthetic` (4 objects, 6 views, stage 2 for 150 steps, features
  rounded) a margin of 3 gave click mIoU 0.86-0.95 and a margin of 6 gave 0.99. The default
  (4, :mod:`csgs_codec.train.defaults`) is the smallest measured to keep mIoU at 1.0 on the
  training benchmark's scene, since a larger margin costs semantic bits.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from csgs_codec.errors import InputError
from csgs_codec.metrics.ssim import ssim
from csgs_codec.train import defaults

#: Weight of the (1 - SSIM) term in :func:`photometric_loss` (3DGS's lambda_dssim).
SSIM_LOSS_WEIGHT = 0.2
#: Default margin of :func:`inter_mask_contrastive_loss`, in feature units.
CONTRASTIVE_MARGIN = defaults.CONTRASTIVE_MARGIN


def l1_loss(rendered: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean absolute difference of two tensors of the same shape: scalar."""
    _same_shape(rendered, target)
    return torch.mean(torch.abs(rendered - target))


def photometric_loss(rendered: torch.Tensor, target: torch.Tensor,
                     ssim_weight: float = SSIM_LOSS_WEIGHT) -> torch.Tensor:
    """Stage-1 distortion: (1 - w) * L1 + w * (1 - SSIM) of [H, W, 3] images; scalar.

    SSIM runs on the numba kernels where they apply (float32 on the CPU), else in torch.
    """
    return (1.0 - ssim_weight) * l1_loss(rendered, target) + ssim_weight * (
        1.0 - ssim(rendered, target, kernel="auto"))


@dataclass(frozen=True)
class MaskPartition:
    """The pixels of an instance mask grouped by id, computed once and reused every step.

    Attributes:
        shape: (H, W) of the mask.
        kept: [H * W] bool, pixels that belong to some mask (not ``ignore_id``); None: all.
        index: [P] long, the mask (0..M-1, increasing id order) of each kept pixel.
        sizes: [M] pixel count of each mask (float32).
    """

    shape: tuple[int, int]
    kept: torch.Tensor | None
    index: torch.Tensor
    sizes: torch.Tensor

    @property
    def count(self) -> int:
        """Number of masks M."""
        return int(self.sizes.shape[0])

    @classmethod
    def from_mask(cls, mask: torch.Tensor, ignore_id: int | None = None) -> MaskPartition:
        """Partition of an [H, W] integer mask; pixels with ``ignore_id`` belong to no mask.

        Raises:
            InputError: a mask that is not [H, W] integers.
        """
        if mask.ndim != 2:
            raise InputError(f"mask must be [H, W], got {tuple(mask.shape)}", property="mask")
        if mask.dtype.is_floating_point or mask.dtype.is_complex or mask.dtype == torch.bool:
            raise InputError(f"mask must hold integer ids, got {mask.dtype}", property="mask")
        flat = mask.reshape(-1)
        kept = None if ignore_id is None else flat != ignore_id
        _, index = torch.unique(flat if kept is None else flat[kept], return_inverse=True)
        count = int(index.max()) + 1 if index.numel() else 0
        sizes = torch.bincount(index, minlength=count).to(torch.float32)
        return cls((int(mask.shape[0]), int(mask.shape[1])), kept, index, sizes)

    def pixels(self, features: torch.Tensor) -> torch.Tensor:
        """[P, D] features of the kept pixels from an [H, W, D] or [H * W, D] feature map."""
        height, width = self.shape
        if features.ndim == 3:
            if tuple(features.shape[:2]) != self.shape:
                raise InputError(f"features {tuple(features.shape)} do not match the mask "
                                 f"{self.shape}", property="mask")
            features = features.reshape(height * width, features.shape[2])
        elif features.ndim != 2 or features.shape[0] != height * width:
            raise InputError(f"features {tuple(features.shape)} do not match the mask "
                             f"{self.shape}", property="mask")
        return features if self.kept is None else features[self.kept.to(features.device)]

    def means(self, pixels: torch.Tensor) -> torch.Tensor:
        """[M, D] mean of the kept pixels' features [P, D] over each mask."""
        index = self.index.to(pixels.device)
        sums = torch.zeros(self.count, pixels.shape[1], dtype=pixels.dtype,
                           device=pixels.device).index_add(0, index, pixels)
        return sums / self.sizes.to(pixels.device, pixels.dtype)[:, None]


def _partition(mask: torch.Tensor | MaskPartition, ignore_id: int | None) -> MaskPartition:
    if isinstance(mask, MaskPartition):
        return mask
    return MaskPartition.from_mask(mask, ignore_id)


def mask_means(features: torch.Tensor, mask: torch.Tensor | MaskPartition,
               ignore_id: int | None = None) -> torch.Tensor:
    """[M, D] mean feature of each mask, masks in increasing id order.

    Args:
        features: [H, W, D] rendered feature map.
        mask: [H, W] integer instance ids, or their :class:`MaskPartition`.
        ignore_id: pixels with this id belong to no mask (e.g. background); None keeps all.
            Ignored when ``mask`` is already a partition.
    """
    partition = _partition(mask, ignore_id)
    return partition.means(partition.pixels(features))


def intra_mask_smoothing_loss(features: torch.Tensor, mask: torch.Tensor | MaskPartition,
                              ignore_id: int | None = None) -> torch.Tensor:
    """L_s (module notes): mean over masks of the mean squared distance to the mask mean.

    Args:
        features: [H, W, D] (or [H * W, D]) rendered feature map.
        mask: [H, W] integer ids, or their :class:`MaskPartition`.
        ignore_id: id of pixels that belong to no mask, or None.

    Returns:
        Scalar; 0 when no mask has a pixel.
    """
    partition = _partition(mask, ignore_id)
    pixels = partition.pixels(features)
    if partition.count == 0:
        return features.sum() * 0.0
    index = partition.index.to(pixels.device)
    means = partition.means(pixels)
    squared = torch.sum((pixels - means[index]) ** 2, dim=1)
    per_mask = torch.zeros(partition.count, dtype=pixels.dtype,
                           device=pixels.device).index_add(0, index, squared)
    return torch.mean(per_mask / partition.sizes.to(pixels.device, pixels.dtype))


def inter_mask_contrastive_loss(features: torch.Tensor, mask: torch.Tensor | MaskPartition,
                                margin: float = CONTRASTIVE_MARGIN,
                                ignore_id: int | None = None) -> torch.Tensor:
    """L_c (module notes): mean over mask pairs of relu(margin - ||mu_a - mu_b||)^2.

    Args:
        features: [H, W, D] (or [H * W, D]) rendered feature map.
        mask: [H, W] integer ids, or their :class:`MaskPartition`.
        margin: distance beyond which a pair costs nothing, feature units (> 0).
        ignore_id: id of pixels that belong to no mask, or None.

    Returns:
        Scalar; 0 with fewer than two masks. The distance is sqrt(d^2 + 1e-12) so that the
        gradient exists when two means coincide.
    """
    if not margin > 0:
        raise InputError(f"margin must be positive, got {margin}", property="margin")
    means = mask_means(features, mask, ignore_id)
    count = means.shape[0]
    if count < 2:
        return features.sum() * 0.0
    first, second = torch.triu_indices(count, count, offset=1, device=means.device)
    distance = torch.sqrt(torch.sum((means[first] - means[second]) ** 2, dim=1) + 1e-12)
    return torch.mean(torch.relu(margin - distance) ** 2)


def _same_shape(a: torch.Tensor, b: torch.Tensor) -> None:
    if a.shape != b.shape:
        raise InputError(f"shapes differ: {tuple(a.shape)} vs {tuple(b.shape)}",
                         property="image")
