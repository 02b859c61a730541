"""Render sensitivities: how much each Gaussian's attributes matter to the pictures.

A Gaussian's color enters a pixel through its blending weight w = alpha * T (its opacity
there times the transmittance in front of it). An error e in its color changes that pixel by
w * e, so over a set of views its squared color error weighs

    W_i = sum over views and pixels of w_i^2

in the rendered MSE (exactly, for the DC color; SH bands add their basis value per view).
W is the sensitivity the step classes of the color layer follow: high-rate theory gives a
step proportional to W^(-1/2) for the smallest rate at a given MSE. Gaussians with W = 0
reach no pixel of any view.

The pass renders every view once with the numba kernels (no gradients).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from csgs_codec.errors import UnsupportedError
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.rasterize_numba import TILE_SIZE
from csgs_codec.render.rasterize_torch import prepare_gaussians
from csgs_codec.render.rasterizer import scene_tensors
from csgs_codec.render.tiles import depth_order, tile_rectangles
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene


@dataclass(frozen=True)
class Sensitivity:
    """Per-Gaussian blending-weight sums over a set of views.

    Attributes:
        weight_sq: (N,) float64 W_i = sum of w^2 over views and pixels (color sensitivity,
            in pixels).
        weight_sum: (N,) float64 sum of w over views and pixels (the Gaussian's share of
            the pictures, in pixels).
        views: number of views rendered.
        seconds: wall time of the pass.
    """

    weight_sq: np.ndarray
    weight_sum: np.ndarray
    views: int
    seconds: float

    @property
    def unseen(self) -> np.ndarray:
        """(N,) bool: Gaussians that reach no pixel of any view."""
        return self.weight_sum <= 0


def blend_sensitivity(scene: GaussianScene, cameras: list[Camera],
                      progress: Callable[[int, int], None] | None = None) -> Sensitivity:
    """Sum each Gaussian's blending weights over ``cameras`` (see the module notes).

    Args:
        scene: the Gaussians, N of them.
        cameras: the views (their sizes set the pixel grids).
        progress: called as ``progress(done, total)`` after each view, or None.

    Raises:
        UnsupportedError: numba is not installed (``pip install 'csgs[fast]'``).
    """
    if not numba_available():
        raise UnsupportedError("render sensitivities need numba: pip install 'csgs[fast]'")
    from csgs_codec.render import numba_kernels as kernels

    start = time.perf_counter()
    n = len(scene)
    weight_sq = np.zeros(n, np.float64)
    weight_sum = np.zeros(n, np.float64)
    tensors = scene_tensors(scene)
    # Color does not change where a Gaussian lands or its weights: DC alone is enough.
    colors = torch.zeros((n, 3), dtype=tensors["means"].dtype, device=tensors["means"].device)
    for done, camera in enumerate(cameras, start=1):
        with torch.no_grad():
            prepared = prepare_gaussians(tensors["means"], tensors["log_scales"],
                                         tensors["quats"], tensors["opacity_logits"], camera,
                                         colors=colors, near_plane=camera.near_plane)
            proj = prepared.projected
            tiles_x = math.ceil(camera.width / TILE_SIZE)
            tiles_y = math.ceil(camera.height / TILE_SIZE)
            rects = tile_rectangles(proj, camera.width, camera.height, TILE_SIZE).numpy()
            order = depth_order(proj.depths, proj.visible).numpy()
            means2d = np.ascontiguousarray(proj.means2d.to(torch.float32).numpy())
            conics = np.ascontiguousarray(proj.conics.to(torch.float32).numpy())
            opacities = np.ascontiguousarray(proj.opacities.to(torch.float32).numpy())
        offsets, ids = kernels.bin_tiles(rects, order, tiles_x * tiles_y, tiles_x, TILE_SIZE,
                                         camera.width, camera.height, means2d, conics,
                                         opacities)
        slot_sq = np.zeros(len(ids), np.float64)
        slot_sum = np.zeros(len(ids), np.float64)
        kernels.blend_weight_slots(offsets, ids, means2d, conics, opacities, camera.width,
                                   camera.height, TILE_SIZE, tiles_x, slot_sq, slot_sum)
        weight_sq += np.bincount(ids, weights=slot_sq, minlength=n)
        weight_sum += np.bincount(ids, weights=slot_sum, minlength=n)
        if progress is not None:
            progress(done, len(cameras))
    return Sensitivity(weight_sq, weight_sum, len(cameras), time.perf_counter() - start)
