"""CUDA rasterization through gsplat, used when torch sees a GPU and gsplat is installed.

Colors come from this package's SH evaluation (:func:`csgs_codec.render.sh.sh_to_color`), so
only projection and compositing are gsplat's. gsplat bounds each footprint at three standard
deviations where the reference uses the exact 1/255 alpha contour, so images agree closely
but not to the last bit.

:func:`rasterize_gaussians_gsplat` is the differentiable form training uses on CUDA (same
outputs as :func:`csgs_codec.render.rasterize_torch.rasterize_gaussians`);
:func:`rasterize_gsplat` is the render-to-arrays form behind the ``"gsplat"`` backend.
"""

from __future__ import annotations

import torch

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.render.device_constants import background_tensor, camera_tensors
from csgs_codec.render.projection import DEFAULT_NEAR_PLANE, LOW_PASS_VARIANCE
from csgs_codec.render.rasterize_torch import RasterTensors
from csgs_codec.render.render_output import RenderOutput
from csgs_codec.render.sh import sh_to_color
from csgs_codec.scene.camera import Camera


def gsplat_available() -> bool:
    """True when torch sees a CUDA device and gsplat imports."""
    if not torch.cuda.is_available():
        return False
    try:
        import gsplat  # noqa: F401
    except ImportError:
        return False
    return True


def rasterize_gaussians_gsplat(means: torch.Tensor, log_scales: torch.Tensor,
                               quats: torch.Tensor, opacity_logits: torch.Tensor | None,
                               camera: Camera, *, opacities: torch.Tensor | None = None,
                               sh: torch.Tensor | None = None,
                               colors: torch.Tensor | None = None,
                               features: torch.Tensor | None = None,
                               background: torch.Tensor | tuple[float, float, float] | None
                               = None,
                               near_plane: float = DEFAULT_NEAR_PLANE,
                               with_depth: bool = True) -> RasterTensors:
    """Render one view with gsplat's ``rasterization``, differentiably, on the inputs' GPU.

    Args:
        means: [N, 3] world positions on a CUDA device; log_scales: [N, 3] natural-log
            scales; quats: [N, 4] rotations (w, x, y, z), normalised by gsplat;
            opacity_logits: [N] opacities before the sigmoid.
        camera: the view (its size sets H, W).
        sh: [N, K, 3] SH coefficients (DC first), evaluated by this package, or
        colors: [N, 3] colors used as they are (exactly one of the two).
        features: optional [N, F] per-Gaussian features, accumulated like colors.
        background: RGB behind the scene, default black.
        near_plane: camera-space z (world units) below which Gaussians are culled.
        with_depth: False (without ``features``): gsplat renders RGB only and composites
            the background itself, and depth is None (training's form: fewer operators).

    Returns:
        :class:`RasterTensors` in float32 on the inputs' device: image [H, W, 3] with the
        background composited behind, alpha [H, W], depth [H, W] (expected z, 0 where alpha
        is 0) or None, features [H, W, F] or None; each differentiable with respect to every
        tensor argument.

    Raises:
        UnsupportedError: gsplat missing or the inputs not on a CUDA device.
        InputError: both or neither of ``sh`` and ``colors`` (or of the two opacity forms),
            or mis-shaped features.
    """
    if not means.is_cuda or not gsplat_available():
        raise UnsupportedError("the gsplat rasterizer needs CUDA tensors and gsplat installed")
    if (sh is None) == (colors is None):
        raise InputError("give exactly one of sh and colors", property="sh")
    if (opacity_logits is None) == (opacities is None):
        raise InputError("give exactly one of opacity_logits and opacities",
                         property="opacities")
    if opacities is None:
        opacities = torch.sigmoid(opacity_logits.to(torch.float32))
    from gsplat import rasterization

    device, n = means.device, means.shape[0]
    means = means.to(torch.float32)
    matrices = camera_tensors(camera, device)
    w2c, intrinsics = matrices.world_to_camera, matrices.intrinsics
    if sh is not None:
        colors = sh_to_color(sh.to(torch.float32), means - matrices.position)
    channels = [colors.to(torch.float32)]
    if features is not None:
        if features.ndim != 2 or features.shape[0] != n:
            raise InputError(f"expected [N, F] with N = {n}, got {tuple(features.shape)}",
                             property="features")
        channels.append(features.to(torch.float32))
    values = torch.cat(channels, dim=1) if len(channels) > 1 else channels[0]
    bg = background_tensor(background, device)
    # Training's form: RGB only, gsplat compositing the background in its kernel.
    rgb_only = not with_depth and features is None
    rendered, alphas, _ = rasterization(
        means, quats.to(torch.float32), torch.exp(log_scales.to(torch.float32)),
        opacities.to(torch.float32), values, w2c[None], intrinsics[None],
        camera.width, camera.height, near_plane=near_plane, eps2d=LOW_PASS_VARIANCE,
        sh_degree=None, backgrounds=bg[None] if rgb_only else None,
        render_mode="RGB" if rgb_only else "RGB+ED", rasterize_mode="classic", packed=False)
    rendered, alpha = rendered[0], alphas[0, ..., 0]
    if rgb_only:
        return RasterTensors(rendered, alpha, None, None)
    image = rendered[..., :3] + (1.0 - alpha)[..., None] * bg
    depth = torch.where(alpha > 0, rendered[..., -1], torch.zeros_like(alpha))
    feats = rendered[..., 3:-1] if features is not None else None
    return RasterTensors(image, alpha, depth, feats)


def rasterize_gsplat(means: torch.Tensor, log_scales: torch.Tensor, quats: torch.Tensor,
                     opacity_logits: torch.Tensor, sh: torch.Tensor, camera: Camera, *,
                     features: torch.Tensor | None = None,
                     background: tuple[float, float, float] = (0.0, 0.0, 0.0),
                     near_plane: float = DEFAULT_NEAR_PLANE) -> RenderOutput:
    """Render one view on the GPU with gsplat and copy the maps back as arrays.

    Args:
        means: [N, 3]; log_scales: [N, 3]; quats: [N, 4] (w, x, y, z); opacity_logits: [N];
        sh: [N, K, 3] SH coefficients, DC first (any device; moved to CUDA).
        camera: the view.
        features: optional [N, F] per-Gaussian features.
        background: RGB behind the scene.
        near_plane: camera-space z below which Gaussians are culled.

    Returns:
        :class:`RenderOutput` with backend "gsplat" (float32 arrays on the CPU).

    Raises:
        UnsupportedError: no CUDA device or gsplat not installed.
    """
    if not gsplat_available():
        raise UnsupportedError("the gsplat backend needs a CUDA GPU and gsplat installed")
    device = torch.device("cuda")
    with torch.no_grad():
        out = rasterize_gaussians_gsplat(
            *(t.to(device) for t in (means, log_scales, quats, opacity_logits)), camera,
            sh=sh.to(device), features=None if features is None else features.to(device),
            background=background, near_plane=near_plane)
    feats = None if out.features is None else out.features.cpu().numpy()
    return RenderOutput(out.image.cpu().numpy(), out.alpha.cpu().numpy(),
                        out.depth.cpu().numpy(), feats, "gsplat")
