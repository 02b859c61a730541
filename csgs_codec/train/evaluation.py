"""Scoring a trained anchor scene: held-out view quality and click-selection mIoU."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.model.scaffold import ScaffoldDecoder
from csgs_codec.render.metrics import psnr, ssim
from csgs_codec.render.rasterizer import render
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.semantic.evaluation import click_object_ious, mean_iou
from csgs_codec.train.views import TrainingView


@dataclass
class ViewScores:
    """Mean PSNR (dB) and SSIM of renders against images over some views (nan for none)."""

    psnr: float
    ssim: float
    views: int


def split_views(views: list[TrainingView], test_every: int
                ) -> tuple[list[TrainingView], list[TrainingView]]:
    """(training, held-out) views: every ``test_every``-th view (0, k, 2k, ...) is held out,
    as 3DGS's ``--eval`` does; 0 holds none out, and a single view is never held out."""
    if test_every <= 0 or len(views) < 2:
        return list(views), []
    test = [v for i, v in enumerate(views) if i % test_every == 0]
    train = [v for i, v in enumerate(views) if i % test_every != 0]
    return train, test


def score_views(scene: AnchorScene, views: list[TrainingView], *,
                background: tuple[float, float, float] = (0.0, 0.0, 0.0),
                backend: str = "numba") -> ViewScores:
    """Render ``scene`` (anchors, decoded per view) for each view and compare with its image."""
    if not views:
        return ViewScores(float("nan"), float("nan"), 0)
    decoder = ScaffoldDecoder(scene)
    psnrs, ssims = [], []
    for view in views:
        gaussians = decoder.to_gaussians(view.camera)
        image = np.clip(render(gaussians, view.camera, backend=backend,
                               background=background).image, 0.0, 1.0)
        psnrs.append(psnr(view.image, image))
        ssims.append(ssim(view.image, image))
    return ViewScores(float(np.mean(psnrs)), float(np.mean(ssims)), len(views))


def nearest_labels(positions: np.ndarray, reference_positions: np.ndarray,
                   reference_labels: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """(M,) int32 label of the nearest reference point of each (M, 3) position (a synthetic
    scene's ground-truth labels carried over to trained anchors)."""
    positions = np.asarray(positions, np.float64)
    reference = np.asarray(reference_positions, np.float64)
    labels = np.empty(len(positions), np.int32)
    for start in range(0, len(positions), chunk):
        block = positions[start:start + chunk]
        distance = ((block[:, None, :] - reference[None, :, :]) ** 2).sum(axis=2)
        labels[start:start + chunk] = np.asarray(reference_labels)[np.argmin(distance, axis=1)]
    return labels


def click_miou(scene: AnchorScene, labels: np.ndarray, views: list[TrainingView]) -> float:
    """Mean over views of the click-selection mIoU of ``scene``'s anchors against ``labels``
    ((M,) ground truth), each object clicked at its projected centre."""
    scores = [mean_iou(click_object_ious(scene, view.camera, labels)) for view in views]
    return float(np.mean(scores)) if scores else float("nan")
