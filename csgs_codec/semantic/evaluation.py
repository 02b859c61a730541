"""Scoring click selection against known object labels (IoU per object, mIoU)."""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.semantic.selection import (
    DEFAULT_THRESHOLD,
    check_selection_rule,
    click_selection,
    render_feature_map,
)


def mask_iou(selected: np.ndarray, truth: np.ndarray) -> float:
    """Intersection over union of two (N,) bool masks (1.0 when both are empty)."""
    selected, truth = np.asarray(selected, bool), np.asarray(truth, bool)
    union = int(np.count_nonzero(selected | truth))
    return 1.0 if union == 0 else int(np.count_nonzero(selected & truth)) / union


def object_click_points(positions: np.ndarray, labels: np.ndarray, camera: Camera
                        ) -> dict[int, tuple[float, float]]:
    """Per label, the pixel (x, y) where the mean position of its elements projects.

    Args:
        positions: (N, 3) world positions; labels: (N,) integer labels.

    Returns:
        {label: (x, y)} in pixels, for labels whose centre lies in front of the camera.
    """
    positions = np.asarray(positions, np.float64)
    labels = np.asarray(labels)
    points = {}
    for label in np.unique(labels):
        centre = positions[labels == label].mean(axis=0)
        cam = camera.world_to_camera[:3, :3] @ centre + camera.world_to_camera[:3, 3]
        if cam[2] > 0:
            points[int(label)] = (camera.fx * cam[0] / cam[2] + camera.cx,
                                  camera.fy * cam[1] / cam[2] + camera.cy)
    return points


def click_object_ious(scene: GaussianScene | AnchorScene, camera: Camera,
                      labels: np.ndarray | None = None, *,
                      threshold: float = DEFAULT_THRESHOLD, mode: str = "instance",
                      backend: str = "numba") -> dict[int, float]:
    """Click each labelled object's projected centre and score the selection.

    Args:
        scene: the scene clicked in (Gaussians or anchors).
        camera: the view.
        labels: (N,) ground-truth labels of the elements (default: ``scene.labels``).
        threshold, mode, backend: as :func:`~csgs_codec.semantic.selection.click_selection`.

    Returns:
        {label: IoU of the selection with the elements of that label}; an object whose click
        hits nothing scores 0.

    Raises:
        InputError: no labels, labels of the wrong shape, or a bad mode or threshold.
    """
    check_selection_rule(mode, threshold)
    labels = scene.labels if labels is None else labels
    if labels is None or np.asarray(labels).shape != (len(scene),):
        raise InputError(f"need ({len(scene)},) ground-truth labels", property="labels")
    labels = np.asarray(labels)
    # "instance" mode composites the clicked pixel only (and may run on labels alone).
    feature_map = None if mode == "instance" else render_feature_map(scene, camera,
                                                                     backend=backend)
    ious = {}
    for label, (x, y) in object_click_points(scene.positions, labels, camera).items():
        try:
            mask = click_selection(scene, camera, x, y, threshold=threshold, mode=mode,
                                   feature_map=feature_map).mask
        except InputError:  # the centre is off-image or on the background
            ious[label] = 0.0
            continue
        ious[label] = mask_iou(mask, labels == label)
    return ious


def mean_iou(ious: dict[int, float]) -> float:
    """Mean of the per-object IoUs (0.0 for none)."""
    return float(np.mean(list(ious.values()))) if ious else 0.0
