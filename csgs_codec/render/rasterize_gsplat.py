"""CUDA rasterization through gsplat, used when torch sees a GPU and gsplat is installed.

Colors come from this package's SH evaluation (:func:`csgs_codec.render.sh.sh_to_color`), so
only projection and compositing are gsplat's. gsplat bounds each footprint at three standard
deviations where the reference uses the exact 1/255 alpha contour, so images agree closely
but not to the last bit.
"""

from __future__ import annotations

import numpy as np
import torch

from csgs_codec.errors import UnsupportedError
from csgs_codec.render.projection import DEFAULT_NEAR_PLANE, LOW_PASS_VARIANCE
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


def rasterize_gsplat(means: torch.Tensor, log_scales: torch.Tensor, quats: torch.Tensor,
                     opacity_logits: torch.Tensor, sh: torch.Tensor, camera: Camera, *,
                     features: torch.Tensor | None = None,
                     background: tuple[float, float, float] = (0.0, 0.0, 0.0),
                     near_plane: float = DEFAULT_NEAR_PLANE) -> RenderOutput:
    """Render one view on the GPU with gsplat's ``rasterization``.

    Args:
        means: [N, 3]; log_scales: [N, 3]; quats: [N, 4] (w, x, y, z); opacity_logits: [N];
        sh: [N, K, 3] SH coefficients, DC first (any device; moved to CUDA).
        camera: the view.
        features: optional [N, F] per-Gaussian features.
        background: RGB behind the scene.
        near_plane: camera-space z below which Gaussians are culled.

    Returns:
        :class:`RenderOutput` with backend "gsplat" (arrays copied back to the CPU).

    Raises:
        UnsupportedError: no CUDA device or gsplat not installed.
    """
    if not gsplat_available():
        raise UnsupportedError("the gsplat backend needs a CUDA GPU and gsplat installed")
    from gsplat import rasterization

    device = torch.device("cuda")
    means, log_scales, quats, opacity_logits, sh = (
        t.to(device, torch.float32) for t in (means, log_scales, quats, opacity_logits, sh))
    w2c = torch.as_tensor(camera.world_to_camera, dtype=torch.float32, device=device)
    centre = -w2c[:3, :3].T @ w2c[:3, 3]
    channels = [sh_to_color(sh, means - centre)]
    if features is not None:
        channels.append(features.to(device, torch.float32))
    colors = torch.cat(channels, dim=1)
    intrinsics = torch.tensor([[camera.fx, 0.0, camera.cx], [0.0, camera.fy, camera.cy],
                               [0.0, 0.0, 1.0]], dtype=torch.float32, device=device)
    rendered, alphas, _ = rasterization(
        means, quats, torch.exp(log_scales), torch.sigmoid(opacity_logits), colors,
        w2c[None], intrinsics[None], camera.width, camera.height, near_plane=near_plane,
        eps2d=LOW_PASS_VARIANCE, sh_degree=None, render_mode="RGB+ED",
        rasterize_mode="classic")
    rendered = rendered[0].detach().cpu().numpy()
    alpha = alphas[0, ..., 0].detach().cpu().numpy().astype(np.float32)
    bg = np.asarray(background, dtype=np.float32)
    image = rendered[..., :3] + (1.0 - alpha)[..., None] * bg
    depth = np.where(alpha > 0, rendered[..., -1], 0.0).astype(np.float32)
    feats = rendered[..., 3:-1] if features is not None else None
    return RenderOutput(image.astype(np.float32), alpha, depth, feats, "gsplat")
