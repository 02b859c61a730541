"""Fast forward rasterizer on the CPU with numba (optional: ``pip install csgs[fast]``).

Projection and colors come from the torch reference (:func:`prepare_gaussians`, vectorised and
cheap); binning and compositing, the expensive part, run in compiled parallel loops
(:mod:`csgs_codec.render.numba_kernels`). Forward only, no gradients.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch

from csgs_codec.render.numba_loader import rasterizer_kernels
from csgs_codec.render.rasterize_torch import PreparedGaussians
from csgs_codec.render.render_output import RenderOutput
from csgs_codec.render.tiles import depth_order, tile_rectangles
from csgs_codec.scene.camera import Camera

#: Tile side in pixels of the numba kernels (speed only: the result does not depend on it).
TILE_SIZE = 8


class Composited(NamedTuple):
    """What the numba kernels made of one view: their inputs (float32 arrays), the tile lists
    and the accumulated values.

    Attributes:
        offsets, ids: the tile lists of :func:`~csgs_codec.render.numba_kernels.bin_tiles`.
        means2d: [N, 2]; conics: [N, 3]; opacities: [N]; values: [N, C] (RGB, depth, then
            any features), float32 as composited.
        out: [H, W, C] accumulated values; transmittance: [H, W]; walked: [H, W] int32 tile
            slots each pixel went through.
        tile_size, tiles_x: the tiling.
    """

    offsets: np.ndarray
    ids: np.ndarray
    means2d: np.ndarray
    conics: np.ndarray
    opacities: np.ndarray
    values: np.ndarray
    out: np.ndarray
    transmittance: np.ndarray
    walked: np.ndarray
    tile_size: int
    tiles_x: int


def composite_prepared(prepared: PreparedGaussians, camera: Camera, *,
                       features: np.ndarray | None = None,
                       tile_size: int = TILE_SIZE) -> Composited:
    """Bin and composite prepared Gaussians with the numba kernels (the work of
    :func:`rasterize_numba`, before the background and the depth division).

    Raises:
        UnsupportedError: numba is not installed.
    """
    kernels = rasterizer_kernels()
    width, height = camera.width, camera.height
    tiles_x = math.ceil(width / tile_size)
    tiles_y = math.ceil(height / tile_size)
    with torch.no_grad():
        proj = prepared.projected
        rects = tile_rectangles(proj, width, height, tile_size).numpy()
        order = depth_order(proj.depths, proj.visible).numpy()

        def f32(t: torch.Tensor) -> np.ndarray:
            return np.ascontiguousarray(t.detach().to(torch.float32).numpy())

        means2d, conics, opacities = f32(proj.means2d), f32(proj.conics), f32(proj.opacities)
        parts = [f32(prepared.colors), f32(proj.depths)[:, None]]
    if features is not None:
        parts.append(np.asarray(features, dtype=np.float32))
    values = np.ascontiguousarray(np.concatenate(parts, axis=1))
    offsets, ids = kernels.bin_tiles(rects, order, tiles_x * tiles_y, tiles_x, tile_size,
                                     width, height, means2d, conics, opacities)
    out = np.zeros((height, width, values.shape[1]), np.float32)
    transmittance = np.ones((height, width), np.float32)
    walked = np.zeros((height, width), np.int32)
    kernels.composite_tiles(offsets, ids, means2d, conics, opacities, values, width, height,
                            tile_size, tiles_x, out, transmittance, walked)
    return Composited(offsets, ids, means2d, conics, opacities, values, out, transmittance,
                      walked, tile_size, tiles_x)


def with_background(rgb: np.ndarray, transmittance: np.ndarray,
                    background: tuple[float, float, float]) -> np.ndarray:
    """[H, W, 3] image: accumulated ``rgb`` [H, W, 3] over ``background`` seen through
    ``transmittance`` [H, W] (float32)."""
    return rgb + transmittance[..., None] * np.asarray(background, dtype=np.float32)


def rasterize_numba(prepared: PreparedGaussians, camera: Camera, *,
                    features: np.ndarray | None = None,
                    background: tuple[float, float, float] = (0.0, 0.0, 0.0),
                    tile_size: int = TILE_SIZE) -> RenderOutput:
    """Composite prepared Gaussians with the numba kernels.

    Args:
        prepared: projected Gaussians and colors from
            :func:`csgs_codec.render.rasterize_torch.prepare_gaussians` (any float dtype;
            compositing runs in float32).
        camera: the view (its size sets H, W).
        features: optional (N, F) per-Gaussian features to render.
        background: RGB behind the scene.
        tile_size: tile side in pixels.

    Returns:
        :class:`RenderOutput` with backend "numba".

    Raises:
        UnsupportedError: numba is not installed.
    """
    done = composite_prepared(prepared, camera, features=features, tile_size=tile_size)
    out, transmittance = done.out, done.transmittance
    image = with_background(out[..., :3], transmittance, background)
    alpha = np.float32(1.0) - transmittance
    depth = np.where(alpha > 0, out[..., 3] / np.where(alpha > 0, alpha, 1), 0)
    feats = out[..., 4:] if features is not None else None
    return RenderOutput(image, alpha, depth.astype(np.float32), feats, "numba")
