"""Recolouring a rendered view without compositing it again (numba backend, forward only).

A pixel's colour is a weighted sum of its Gaussians' colours, the weights w = alpha T fixed
by where the Gaussians lie, their shapes and opacities. :func:`render_recording` renders a
view as :func:`csgs_codec.render.rasterizer.render` does with the numba backend and also
keeps each pixel's (Gaussian, weight) pairs in compositing order; :meth:`BlendRecord.recolour`
then gives the image of the same Gaussians with other SH coefficients in one pass over those
pairs, the same float32 sums in the same order, so bit for bit the image a full render of
them gives. The encoder's step allocation uses it for candidates that change colours only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from csgs_codec.render.numba_loader import rasterizer_kernels
from csgs_codec.render.rasterize_numba import composite_prepared, with_background
from csgs_codec.render.rasterize_torch import prepare_gaussians, view_colors
from csgs_codec.render.rasterizer import check_render_inputs, scene_tensors
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene


@dataclass(frozen=True)
class BlendRecord:
    """Every pixel's (Gaussian, weight) pairs of one numba render, in compositing order.

    Attributes:
        camera: the view.
        background: RGB behind the scene.
        starts: [H W + 1] int64 first entry of each pixel (row-major) in ``ids``/``weights``.
        counts: [H W] int32 pairs of each pixel.
        ids: [E] int32 Gaussian of each pair (rows of the scene rendered).
        weights: [E] float32 blending weight alpha T of each pair.
        transmittance: [H, W] float32 light left behind the last pair.
    """

    camera: Camera
    background: tuple[float, float, float]
    starts: np.ndarray
    counts: np.ndarray
    ids: np.ndarray
    weights: np.ndarray
    transmittance: np.ndarray

    @property
    def nbytes(self) -> int:
        """Memory the record holds, in bytes."""
        return sum(a.nbytes for a in (self.starts, self.counts, self.ids, self.weights,
                                      self.transmittance))

    def recolour(self, scene: GaussianScene) -> np.ndarray:
        """(H, W, 3) float32 image of ``scene``, which must have the rendered scene's
        positions, scales, rotations and opacities (any SH coefficients of the same degree):
        bit for bit what :func:`render_recording` gives for it."""
        tensors = scene_tensors(scene)
        with torch.no_grad():
            colors = view_colors(tensors["means"], tensors["sh"], self.camera)
        values = np.ascontiguousarray(colors.to(torch.float32).numpy())
        height, width = self.transmittance.shape
        out = np.zeros((height * width, 3), np.float32)
        rasterizer_kernels().replay_blend(self.starts, self.counts, self.ids, self.weights,
                                          values, out)
        return with_background(out.reshape(height, width, 3), self.transmittance,
                               self.background)


def render_recording(scene: GaussianScene, camera: Camera, *,
                     background: tuple[float, float, float] = (0.0, 0.0, 0.0),
                     max_slots: int | None = None) -> tuple[np.ndarray, BlendRecord | None]:
    """((H, W, 3) float32 image, its :class:`BlendRecord`) of one view, the image exactly
    :func:`~csgs_codec.render.rasterizer.render`'s with ``backend="numba"``.

    ``max_slots``: no record (None in its place) when the pixels walked more tile slots than
    this in all (recording takes 8 bytes a slot walked; the record keeps 8 bytes a pair).

    Raises:
        InputError: a bad camera, background or scene (as ``render``).
        UnsupportedError: numba is not installed.
    """
    check_render_inputs(scene, camera, None, background)
    tensors = scene_tensors(scene)
    with torch.no_grad():
        prepared = prepare_gaussians(tensors["means"], tensors["log_scales"], tensors["quats"],
                                     tensors["opacity_logits"], camera, sh=tensors["sh"],
                                     near_plane=camera.near_plane)
    done = composite_prepared(prepared, camera)
    image = with_background(done.out[..., :3], done.transmittance, background)
    walked = done.walked.reshape(-1).astype(np.int64)
    if max_slots is not None and int(walked.sum()) > max_slots:
        return image, None
    starts = np.zeros(walked.size + 1, np.int64)
    np.cumsum(walked, out=starts[1:])
    ids = np.empty(int(starts[-1]), np.int32)
    weights = np.empty(int(starts[-1]), np.float32)
    counts = np.zeros(walked.size, np.int32)
    rasterizer_kernels().record_blend(done.offsets, done.ids, done.means2d, done.conics,
                                      done.opacities, camera.width, camera.height,
                                      done.tile_size, done.tiles_x, starts, ids, weights,
                                      counts)
    # Keep the pairs alone: a pixel walks past Gaussians that miss it (about half the slots
    # of a real capture's probe views).
    total = int(counts.sum(dtype=np.int64))
    kept = np.zeros(walked.size + 1, np.int64)
    np.cumsum(counts, out=kept[1:])
    positions = np.arange(total, dtype=np.int64) + np.repeat(starts[:-1] - kept[:-1], counts)
    return image, BlendRecord(camera, tuple(background), kept, counts, ids[positions],
                              weights[positions], done.transmittance)
