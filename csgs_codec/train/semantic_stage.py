"""Stages 2 and 3: learn per-anchor semantic features from 2D instance masks, geometry fixed.

With the geometry and colors frozen (as in stages 2 and 3), each pixel's rendered feature is
linear in the per-Gaussian features: F_p = sum_i alpha_i T_i(p) v_i. So each view is rendered
once into a sparse contribution matrix C (pixels x groups, a group being an anchor whose
Gaussians share one feature, or a single Gaussian), and every training step is a sparse
product instead of a rasterization. The rendered value of group g is

    v_g = (s_g + u_g) * w_g,   u_g ~ U(-Q/2, Q/2) (Q = 1),   w = quality_aware_weights(q_f)

(the noise proxy of quantization and the quality-aware weighting of docs/design.md, 'Training') and
the loss of a view is L_s + lambda_c L_c over its mask (:mod:`csgs_codec.train.losses`),
averaged over views. Stage 3 adds lambda_rate * R, R the mean over groups of the bits of
s_g + u_g under an entropy model (:func:`csgs_codec.train.quantization.gaussian_rate_bits`
with the model's mean and sigma, step Q), the model trained jointly; stage 2 is
lambda_rate = 0. Adam minimises the sum. Deterministic on the CPU from ``seed``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from csgs_codec.errors import InputError
from csgs_codec.render.composite_torch import composite_weights
from csgs_codec.render.projection import project_gaussians
from csgs_codec.render.rasterizer import scene_tensors
from csgs_codec.render.tiles import depth_order
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.train.feature_prior import FactorizedGaussianPrior
from csgs_codec.train.losses import CONTRASTIVE_MARGIN
from csgs_codec.train.plain_adam import PlainAdam
from csgs_codec.train.quantization import (
    add_quantization_noise,
    gaussian_rate_bits,
    quality_aware_weights,
)
from csgs_codec.train.semantic_batch import ViewBatch
from csgs_codec.train.views import TrainingView

#: Width D of the semantic feature s (docs/design.md, 'Training').
SEMANTIC_DIM = 6
#: Contributions below this weight are dropped from the contribution matrix.
MIN_CONTRIBUTION = 1e-4


@dataclass
class SemanticView:
    """One view prepared for stage 2.

    Attributes:
        contributions: sparse COO (H * W, G) float32, the summed alpha * T of each group's
            Gaussians at each pixel (row-major pixels).
        mask: (H, W) int64 instance ids (any device: training moves both to its own).
    """

    contributions: torch.Tensor
    mask: torch.Tensor


@dataclass
class SemanticResult:
    """What :func:`train_semantic_features` returns.

    Attributes:
        features: (G, D) float32 semantic feature s per group, in quantization steps (round it
            to code it with step Q = 1).
        losses: (iterations,) float64 training loss per step (rate term included).
        bits: (iterations,) float64 estimated bits per group of the noisy features under the
            entropy model, per step (0 when ``rate_weight`` is 0 and no model is given).
        rate_model: the entropy model after training, or None.
    """

    features: np.ndarray
    losses: np.ndarray
    bits: np.ndarray
    rate_model: torch.nn.Module | None = None


def contribution_matrix(scene: GaussianScene, camera: Camera, groups: np.ndarray | None = None,
                        *, group_count: int | None = None,
                        device: str | torch.device = "cpu") -> torch.Tensor:
    """Sparse (H * W, G) float32 matrix of each group's rendered weight at each pixel.

    Rendering a feature map of the scene with per-Gaussian features v gives
    ``(contributions @ v_groups).reshape(H, W, D)`` when Gaussians of a group share v. One
    pass of the reference compositor gives every contributing (pixel, Gaussian) pair and its
    weight alpha * T (:func:`csgs_codec.render.composite_torch.composite_weights`), so the
    cost is one render whatever N or G; weights below :data:`MIN_CONTRIBUTION` are dropped
    after the Gaussians of a group are summed.

    Args:
        scene: the Gaussians as seen from this camera (e.g. an anchor scene decoded for it).
        camera: the view.
        groups: (N,) int, the group (anchor) of each Gaussian in [0, G); None: one per Gaussian.
        group_count: G (default: max(groups) + 1, or N).
        device: where the projection, the compositing and the returned matrix live.

    Raises:
        InputError: groups of the wrong shape or out of range.
    """
    n = len(scene)
    groups = np.arange(n) if groups is None else np.asarray(groups)
    if groups.shape != (n,) or (n and not np.issubdtype(groups.dtype, np.integer)):
        raise InputError(f"groups must be (N,) = ({n},) integers, got {groups.shape} "
                         f"{groups.dtype}", property="groups")
    count = (int(groups.max()) + 1 if n else 0) if group_count is None else int(group_count)
    if n and (groups.min() < 0 or groups.max() >= count):
        raise InputError(f"groups must lie in [0, {count})", property="groups")
    pixel_count = camera.width * camera.height
    tensors = scene_tensors(scene, device=device)
    with torch.no_grad():
        projected = project_gaussians(tensors["means"], tensors["log_scales"], tensors["quats"],
                                      tensors["opacity_logits"], camera,
                                      near_plane=camera.near_plane)
        order = depth_order(projected.depths, projected.visible)
        pixel, gaussian, weight = composite_weights(
            order, projected.means2d, projected.conics, projected.opacities,
            projected.extents, camera.width, camera.height)
    group = torch.as_tensor(groups.astype(np.int64), device=gaussian.device)[gaussian]
    # Indices come from the compositor and the checked groups, so they are in range.
    matrix = torch.sparse_coo_tensor(torch.stack([pixel, group]), weight.to(torch.float32),
                                     (pixel_count, count), check_invariants=False,
                                     device=weight.device).coalesce()
    keep = matrix.values() > MIN_CONTRIBUTION
    return torch.sparse_coo_tensor(matrix.indices()[:, keep], matrix.values()[keep],
                                   (pixel_count, count), is_coalesced=True,
                                   check_invariants=False, device=weight.device)


def prepare_semantic_views(scene: GaussianScene, views: list[TrainingView],
                           groups: np.ndarray | None = None, *, group_count: int | None = None,
                           device: str | torch.device = "cpu") -> list[SemanticView]:
    """:class:`SemanticView` s of training views whose Gaussians stay ``scene`` in every view.

    Args:
        scene: the Gaussians; groups, group_count, device: as for
            :func:`contribution_matrix`.
        views: training views, each with a mask.

    Raises:
        InputError: a view without a mask.
    """
    prepared = []
    for i, view in enumerate(views):
        if view.mask is None:
            raise InputError("stage 2 needs an instance mask for every view",
                             file=view.name or None, index=i, property="mask")
        matrix = contribution_matrix(scene, view.camera, groups, group_count=group_count,
                                     device=device)
        prepared.append(SemanticView(matrix, torch.as_tensor(view.mask.astype(np.int64),
                                                             device=matrix.device)))
    return prepared


def train_semantic_features(views: list[SemanticView], group_count: int, *,
                            color_steps: np.ndarray | None = None, dim: int = SEMANTIC_DIM,
                            iterations: int = 200, learning_rate: float = 0.1,
                            noise_step: float = 1.0, margin: float = CONTRASTIVE_MARGIN,
                            contrastive_weight: float = 1.0, ignore_id: int | None = None,
                            initial_scale: float = 0.1, rate_weight: float = 0.0,
                            rate_model: torch.nn.Module | None = None, seed: int = 0,
                            device: str | torch.device = "cpu",
                            initial_features: np.ndarray | None = None,
                            step_range: tuple[float, float] | None = None,
                            on_step: Callable[[int], None] | None = None,
                            batch: ViewBatch | None = None) -> SemanticResult:
    """Fit the semantic feature of every group to the views' masks (module notes).

    Args:
        views: prepared views (:func:`contribution_matrix` and a mask each); may be empty
            when ``batch`` holds them.
        group_count: G, the number of groups (anchors).
        color_steps: (G,) stage-1 color quantization step q_f per group for the
            quality-aware weights; None weighs every group 1.
        dim: feature width D.
        iterations: Adam steps, each over every view.
        learning_rate: Adam step size (feature units).
        noise_step: Q of the uniform quantization noise (0 turns it off).
        margin: the contrastive margin.
        contrastive_weight: lambda_c.
        ignore_id: mask id of pixels that belong to no instance, or None.
        initial_scale: standard deviation of the random initial features (small, so that
            Gaussians no view constrains stay near 0 rather than at random directions).
        rate_weight: lambda_rate of stage 3, weighing bits per group against the stage-2 loss
            (0: stage 2).
        rate_model: module mapping the noisy features [G, D] to (mean, sigma) [G, D] in
            quantization steps, trained jointly; default a :class:`FactorizedGaussianPrior`
            when ``rate_weight`` > 0.
        seed: seeds the initial features and the noise (bit-reproducible on the CPU).
        device: torch device to train on ("cpu", "cuda", ...).
        initial_features: (G, D) features to start from (stage 3 continues stage 2's);
            default random (``initial_scale``).
        step_range: the codec's (low, high) color steps for the quality-aware weights (see
            :func:`quality_aware_weights`); None normalises min-max over the groups.
        on_step: called with the step index (0-based) after every step (progress bars).
        batch: ``views`` already stacked (:class:`ViewBatch`, same ``ignore_id`` and
            ``device``), for a caller that needs the batch afterwards; None stacks them here.

    Returns:
        :class:`SemanticResult`.

    Raises:
        InputError: no views, a view whose matrix and mask disagree with each other or G, or
            a rate term without a quantization step.
    """
    if not views and batch is None:
        raise InputError("stage 2 needs at least one view", property="views")
    if batch is None:
        batch = ViewBatch.from_views([view.contributions for view in views],
                                     [view.mask for view in views], group_count,
                                     ignore_id=ignore_id, device=device)
    weights = (torch.ones(group_count, device=device) if color_steps is None
               else quality_aware_weights(np.asarray(color_steps, np.float32),
                                             step_range=step_range))
    if weights.shape != (group_count,):
        raise InputError(f"color_steps must be ({group_count},)", property="color_steps")
    weights = weights.to(device)
    # The initial features come from a CPU generator so every device starts from the same s.
    initial_generator = torch.Generator(device="cpu")  # cpu: the same s on every device
    initial_generator.manual_seed(seed)
    start = initial_scale * torch.randn(group_count, dim, generator=initial_generator,
                                        device=initial_generator.device)
    if initial_features is not None:
        initial = np.asarray(initial_features, np.float32)
        if initial.shape != (group_count, dim) or not np.isfinite(initial).all():
            raise InputError(f"initial features must be finite ({group_count}, {dim}), got "
                             f"{initial.shape}", property="initial_features")
        # A copy: training updates it in place, and the caller's array must stay as it is.
        start = torch.as_tensor(initial.copy(), device=device)
    features = start.to(device).requires_grad_(True)
    generator = torch.Generator(device=device).manual_seed(seed + 1)
    if rate_model is None and rate_weight > 0:
        rate_model = FactorizedGaussianPrior(dim, device=device)
    if rate_model is not None and not noise_step > 0:
        raise InputError("the rate term needs a quantization step noise_step > 0",
                         property="noise_step")
    parameters = [features]
    if rate_model is not None:
        rate_model = rate_model.to(device)
        parameters += list(rate_model.parameters())
    optimizer = PlainAdam(parameters, lr=learning_rate)
    history = np.zeros(iterations)
    bits_history = np.zeros(iterations)
    for step in range(iterations):
        optimizer.zero_grad()
        noisy = add_quantization_noise(features, noise_step, generator=generator)
        values = noisy * weights[:, None]
        loss = batch.loss(values, margin, contrastive_weight)
        if rate_model is not None:
            mean, sigma = rate_model(noisy)
            bits = gaussian_rate_bits(noisy, mean, sigma, noise_step).sum(dim=1).mean()
            loss = loss + rate_weight * bits
            bits_history[step] = bits.item()
        loss.backward()
        optimizer.step()
        history[step] = loss.item()
        if on_step is not None:
            on_step(step)
    return SemanticResult(features.detach().cpu().numpy().astype(np.float32), history,
                          bits_history, rate_model)
