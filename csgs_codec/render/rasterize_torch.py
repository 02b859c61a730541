"""The differentiable reference rasterizer (pure torch, on the device of its inputs).

Use :func:`rasterize_gaussians` for training: every output is differentiable with respect to
means, log-scales, quaternions, opacity logits, SH coefficients (or colors) and features.
The numba and gsplat paths are tested against this one.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from csgs_codec.errors import InputError
from csgs_codec.render.composite_numba import composite_numba, numba_compositing_usable
from csgs_codec.render.composite_torch import composite
from csgs_codec.render.projection import (
    DEFAULT_NEAR_PLANE,
    ProjectedGaussians,
    project_gaussians,
)
from csgs_codec.render.sh import sh_to_color
from csgs_codec.render.tiles import depth_order
from csgs_codec.scene.camera import Camera

#: Compositors :func:`rasterize_gaussians` accepts.
COMPOSITORS = ("torch", "numba", "auto")


class RasterTensors(NamedTuple):
    """Rendered maps as tensors (dtype of the inputs).

    Attributes:
        image: [H, W, 3] linear RGB, background composited behind.
        alpha: [H, W] accumulated opacity, 1 - final transmittance.
        depth: [H, W] expected camera-space z of what the pixel sees (accumulated weight * z
            divided by alpha), 0 where alpha is 0; None where the caller did not ask for it
            and the rasterizer skips it (``with_depth=False``).
        features: [H, W, F] accumulated weight * feature (no background), or None.
    """

    image: torch.Tensor
    alpha: torch.Tensor
    depth: torch.Tensor | None
    features: torch.Tensor | None


class PreparedGaussians(NamedTuple):
    """Per-Gaussian screen-space data every backend composites from.

    Attributes:
        projected: :class:`csgs_codec.render.projection.ProjectedGaussians`.
        colors: [N, 3] view-dependent RGB (0.5 + SH, clamped at 0).
    """

    projected: ProjectedGaussians
    colors: torch.Tensor


def view_colors(means: torch.Tensor, sh: torch.Tensor, camera: Camera) -> torch.Tensor:
    """[N, 3] RGB of Gaussians at ``means`` [N, 3] with SH coefficients ``sh`` [N, K, 3] seen
    from ``camera``'s centre (0.5 + SH, clamped at 0), as every backend composites them."""
    rot, trans = camera.world_to_camera[:3, :3], camera.world_to_camera[:3, 3]
    centre = torch.as_tensor(-rot.T @ trans, dtype=means.dtype, device=means.device)
    return sh_to_color(sh, means - centre)


def prepare_gaussians(means: torch.Tensor, log_scales: torch.Tensor, quats: torch.Tensor,
                      opacity_logits: torch.Tensor, camera: Camera, *,
                      sh: torch.Tensor | None = None, colors: torch.Tensor | None = None,
                      near_plane: float = DEFAULT_NEAR_PLANE) -> PreparedGaussians:
    """Project Gaussians and evaluate their color for this camera.

    Args:
        means: [N, 3]; log_scales: [N, 3]; quats: [N, 4] (w, x, y, z); opacity_logits: [N].
        camera: the view.
        sh: [N, K, 3] SH coefficients, K in {1, 4, 9, 16}, DC first; or
        colors: [N, 3] colors used as they are (exactly one of ``sh`` and ``colors``).
        near_plane: camera-space z below which Gaussians are culled.

    Returns:
        :class:`PreparedGaussians`.
    """
    n = means.shape[0]
    for name, t, tail in (("means", means, (3,)), ("log_scales", log_scales, (3,)),
                          ("quats", quats, (4,)), ("opacity_logits", opacity_logits, ())):
        if tuple(t.shape) != (n,) + tail:
            raise InputError(f"expected shape {(n,) + tail}, got {tuple(t.shape)}",
                             property=name)
    if (sh is None) == (colors is None):
        raise InputError("give exactly one of sh and colors", property="sh")
    projected = project_gaussians(means, log_scales, quats, opacity_logits, camera,
                                  near_plane=near_plane)
    if sh is not None:
        if sh.ndim != 3 or sh.shape[0] != n or sh.shape[2] != 3 or sh.shape[1] not in (1, 4, 9,
                                                                                     16):
            raise InputError(f"expected [N, K, 3] with K in 1, 4, 9, 16, got {tuple(sh.shape)}",
                             property="sh")
        colors = view_colors(means, sh, camera)
    elif tuple(colors.shape) != (n, 3):
        raise InputError(f"expected shape {(n, 3)}, got {tuple(colors.shape)}",
                         property="colors")
    return PreparedGaussians(projected, colors)


def rasterize_gaussians(means: torch.Tensor, log_scales: torch.Tensor, quats: torch.Tensor,
                        opacity_logits: torch.Tensor, camera: Camera, *,
                        sh: torch.Tensor | None = None, colors: torch.Tensor | None = None,
                        features: torch.Tensor | None = None,
                        background: torch.Tensor | tuple[float, float, float] | None = None,
                        near_plane: float = DEFAULT_NEAR_PLANE,
                        compositor: str = "torch", with_depth: bool = True) -> RasterTensors:
    """Render Gaussians to an image, differentiably (the reference rasterizer).

    Args:
        means: [N, 3] world positions.
        log_scales: [N, 3] natural-log scales.
        quats: [N, 4] rotations (w, x, y, z), normalised internally.
        opacity_logits: [N] opacities before the sigmoid.
        camera: pinhole camera (its size sets H, W).
        sh: [N, K, 3] SH coefficients (K = 1, 4, 9 or 16, DC first) or
        colors: [N, 3] colors (exactly one of the two).
        features: optional [N, F] per-Gaussian features to render (e.g. semantics).
        background: RGB behind the scene, default black.
        near_plane: camera-space z (world units) below which Gaussians are culled.
        compositor: "torch" (the reference, any dtype and device), "numba" (float32 on the
            CPU, several times faster forward and backward; needs numba) or "auto" (numba
            when the inputs allow it and numba is installed, else torch). Projection and
            colors are torch in every case.
        with_depth: composite the depth map (False: ``depth`` is None, and the compositor
            carries one value fewer per Gaussian; image, alpha and features are the same
            numbers either way, and so are their gradients).

    Returns:
        :class:`RasterTensors`, each differentiable with respect to every tensor argument.
    """
    if compositor not in COMPOSITORS:
        raise InputError(f"unknown compositor {compositor!r}; expected one of {COMPOSITORS}",
                         property="compositor")
    dtype = means.dtype
    prepared = prepare_gaussians(means, log_scales, quats, opacity_logits, camera, sh=sh,
                                 colors=colors, near_plane=near_plane)
    proj = prepared.projected
    n = means.shape[0]
    parts = [prepared.colors, proj.depths[:, None]] if with_depth else [prepared.colors]
    if features is not None:
        if features.ndim != 2 or features.shape[0] != n:
            raise InputError(f"expected [N, F] with N = {n}, got {tuple(features.shape)}",
                             property="features")
        parts.append(features.to(dtype))
    values = torch.cat(parts, dim=1)
    order = depth_order(proj.depths, proj.visible)
    use_numba = compositor == "numba" or (
        compositor == "auto" and numba_compositing_usable(proj.means2d, proj.conics, values))
    composite_fn = composite_numba if use_numba else composite
    acc, transmittance = composite_fn(order, proj.means2d, proj.conics,
                                      proj.opacities.to(dtype), proj.extents, values,
                                      camera.width, camera.height)
    bg = (torch.zeros(3, dtype=dtype, device=means.device) if background is None
          else torch.as_tensor(background, dtype=dtype, device=means.device))
    image = acc[..., :3] + transmittance[..., None] * bg
    alpha = 1.0 - transmittance
    depth = None
    if with_depth:
        has_alpha = alpha > 0
        depth = torch.where(has_alpha, acc[..., 3] / torch.where(has_alpha, alpha,
                                                                 torch.ones_like(alpha)),
                            torch.zeros_like(alpha))
    feats = acc[..., 4 if with_depth else 3:] if features is not None else None
    return RasterTensors(image, alpha, depth, feats)
