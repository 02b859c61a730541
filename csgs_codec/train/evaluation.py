"""Scoring a trained anchor scene: held-out view quality and click-selection mIoU."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.metrics.image import foreground_psnr, psnr, ssim
from csgs_codec.model.scaffold import ScaffoldDecoder
from csgs_codec.render.rasterizer import render
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.semantic.evaluation import click_object_ious, mask_iou, mean_iou
from csgs_codec.semantic.selection import (
    click_selection,
    render_feature_map,
    selected_gaussians,
)
from csgs_codec.train.views import TrainingView


@dataclass
class ViewScores:
    """Mean PSNR (dB) and SSIM of renders against images over some views (nan for none), and
    the mean PSNR inside the views' foreground masks (nan unless every view has one)."""

    psnr: float
    ssim: float
    views: int
    foreground_psnr: float = float("nan")


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
    psnrs, ssims, inside = [], [], []
    for view in views:
        gaussians = decoder.to_gaussians(view.camera)
        image = np.clip(render(gaussians, view.camera, backend=backend,
                               background=background).image, 0.0, 1.0)
        psnrs.append(psnr(view.image, image))
        ssims.append(ssim(view.image, image))
        if view.foreground is not None:
            inside.append(foreground_psnr(view.image, image, view.foreground))
    masked = float(np.mean(inside)) if len(inside) == len(views) else float("nan")
    return ViewScores(float(np.mean(psnrs)), float(np.mean(ssims)), len(views), masked)


def nearest_labels(positions: np.ndarray, reference_positions: np.ndarray,
                   reference_labels: np.ndarray, max_pairs: int = 1 << 22) -> np.ndarray:
    """(M,) int32 label of the nearest reference point of each (M, 3) position (a synthetic
    scene's ground-truth labels carried over to trained anchors); works in blocks of at most
    ``max_pairs`` position-reference pairs to bound memory."""
    positions = np.asarray(positions, np.float64)
    reference = np.asarray(reference_positions, np.float64)
    if len(reference) == 0:
        raise InputError("no reference points to take labels from", property="labels")
    chunk = max(1, max_pairs // len(reference))
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


#: Instance masks smaller than this many pixels are not clicked.
MIN_MASK_PIXELS = 16
#: A rendered selection covers a pixel where its accumulated opacity exceeds this.
SELECTION_ALPHA = 0.5


def interior_pixel(mask: np.ndarray) -> tuple[int, int]:
    """(column, row) of a pixel deep inside the (H, W) bool ``mask``: the middle pixel of
    the last non-empty 4-neighbour erosion (a click a user would make, away from edges)."""
    current = np.asarray(mask, bool)
    if not current.any():
        raise InputError("cannot click an empty mask", property="mask")
    while True:
        inner = current.copy()
        inner[1:, :] &= current[:-1, :]
        inner[:-1, :] &= current[1:, :]
        inner[:, 1:] &= current[:, :-1]
        inner[:, :-1] &= current[:, 1:]
        inner[[0, -1], :] = False
        inner[:, [0, -1]] = False
        if not inner.any():
            break
        current = inner
    rows, cols = np.nonzero(current)
    middle = len(rows) // 2
    return int(cols[middle]), int(rows[middle])


def image_click_iou(scene: AnchorScene, view: TrainingView, *, background_id: int = 0,
                    backend: str = "numba") -> dict[int, float]:
    """2D click-selection IoU per instance of ``view.mask`` (the papers' mIoU protocol).

    Each instance (other than ``background_id``, at least :data:`MIN_MASK_PIXELS` pixels) is
    clicked at an interior pixel; the selected anchors are rendered and the pixels where their
    opacity exceeds :data:`SELECTION_ALPHA` are compared with the instance's mask.
    """
    if view.mask is None:
        raise InputError("the view has no instance mask", file=view.name or None,
                         property="mask")
    feature_map = render_feature_map(scene, view.camera, backend=backend)
    ious = {}
    for instance in np.unique(view.mask):
        truth = view.mask == instance
        if instance == background_id or truth.sum() < MIN_MASK_PIXELS:
            continue
        x, y = interior_pixel(truth)
        try:
            selection = click_selection(scene, view.camera, x + 0.5, y + 0.5,
                                        feature_map=feature_map)
        except InputError:  # the click landed where nothing is rendered
            ious[int(instance)] = 0.0
            continue
        chosen = selected_gaussians(scene, selection.mask, view.camera)
        alpha = render(chosen, view.camera, backend=backend).alpha
        ious[int(instance)] = mask_iou((alpha > SELECTION_ALPHA).ravel(), truth.ravel())
    return ious


def image_click_miou(scene: AnchorScene, views: list[TrainingView], *,
                     background_id: int = 0) -> float:
    """Mean over views of the mean :func:`image_click_iou` (nan without views)."""
    scores = [mean_iou(image_click_iou(scene, view, background_id=background_id))
              for view in views]
    return float(np.mean(scores)) if scores else float("nan")
