"""Which differentiable rasterizer training uses, and the one call that renders through it.

``"torch"`` is the reference (:func:`csgs_codec.render.rasterize_torch.rasterize_gaussians`,
with the numba compositor on CPU float32); ``"gsplat"`` is gsplat's CUDA kernels
(:func:`csgs_codec.render.rasterize_gsplat.rasterize_gaussians_gsplat`), tens of times faster
where training runs on a GPU because the reference is bound by the host there. ``"auto"`` picks
gsplat for CUDA tensors when gsplat is installed, else the reference.
"""

from __future__ import annotations

import torch

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.render.projection import DEFAULT_NEAR_PLANE
from csgs_codec.render.rasterize_gsplat import gsplat_available, rasterize_gaussians_gsplat
from csgs_codec.render.rasterize_torch import RasterTensors, rasterize_gaussians
from csgs_codec.scene.camera import Camera

#: Names :func:`resolve_training_rasterizer` accepts.
TRAINING_RASTERIZERS = ("auto", "torch", "gsplat")
#: Opacities given as such are clamped into [eps, 1 - eps] before the logit the torch
#: reference takes.
OPACITY_EPS = 1e-6


def resolve_training_rasterizer(requested: str, device: torch.device | str) -> str:
    """The rasterizer ``requested`` means for tensors on ``device``: "torch" or "gsplat".

    Raises:
        InputError: an unknown name.
        UnsupportedError: "gsplat" asked for where it cannot run (no CUDA device or no gsplat).
    """
    if requested not in TRAINING_RASTERIZERS:
        raise InputError(f"unknown rasterizer {requested!r}; expected one of "
                         f"{TRAINING_RASTERIZERS}", property="rasterizer")
    on_cuda = torch.device(device).type == "cuda"
    if requested == "auto":
        return "gsplat" if on_cuda and gsplat_available() else "torch"
    if requested == "gsplat" and not (on_cuda and gsplat_available()):
        raise UnsupportedError("the gsplat rasterizer needs device cuda and gsplat installed "
                               "(pip install 'csgs[cuda]')")
    return requested


def rasterize_for_training(means: torch.Tensor, log_scales: torch.Tensor, quats: torch.Tensor,
                           opacity_logits: torch.Tensor | None, camera: Camera, *,
                           colors: torch.Tensor, opacities: torch.Tensor | None = None,
                           rasterizer: str = "auto",
                           background: tuple[float, float, float] | None = None,
                           near_plane: float = DEFAULT_NEAR_PLANE,
                           with_depth: bool = True) -> RasterTensors:
    """Render [N] Gaussians with per-Gaussian ``colors`` [N, 3] through the rasterizer
    ``rasterizer`` names for their device (see :func:`resolve_training_rasterizer`).

    Opacity comes as ``opacity_logits`` [N] (before the sigmoid) or as ``opacities`` [N] in
    [0, 1] (then ``opacity_logits`` is None); gsplat takes the second as it is, the torch
    reference takes the logit of it clamped into [:data:`OPACITY_EPS`, 1 - OPACITY_EPS].
    ``with_depth=False`` skips the depth map (then None): gsplat and the reference composite
    one value fewer per Gaussian, and the image, alpha and gradients are the same numbers.

    Returns:
        :class:`RasterTensors` (image [H, W, 3], alpha [H, W], depth [H, W]), differentiable
        with respect to every tensor argument, on the inputs' device.
    """
    if (opacity_logits is None) == (opacities is None):
        raise InputError("give exactly one of opacity_logits and opacities",
                         property="opacities")
    if resolve_training_rasterizer(rasterizer, means.device) == "gsplat":
        return rasterize_gaussians_gsplat(means, log_scales, quats, opacity_logits, camera,
                                          opacities=opacities, colors=colors,
                                          background=background, near_plane=near_plane,
                                          with_depth=with_depth)
    if opacity_logits is None:
        clamped = opacities.clamp(OPACITY_EPS, 1.0 - OPACITY_EPS)
        opacity_logits = torch.log(clamped) - torch.log1p(-clamped)
    # "auto": the numba compositor on CPU float32 (same images and gradients as the torch
    # reference to float32 rounding, several times faster), torch elsewhere.
    return rasterize_gaussians(means, log_scales, quats, opacity_logits, camera, colors=colors,
                               background=background, near_plane=near_plane,
                               compositor="auto", with_depth=with_depth)
