"""The labelled scenes and views the click-selection tests share."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from csgs_codec.scene.camera import Camera
from csgs_codec.semantic.synthetic import labelled_blob_scene, overview_camera

OBJECTS = 5


def five_objects():
    """(scene, camera): 5 labelled blobs, 400 Gaussians each, and a view of all of them."""
    scene = labelled_blob_scene(OBJECTS, 400, seed=3)
    return scene, overview_camera(scene.positions)


def write_inria_cameras(cameras: list[Camera], path: Path) -> Path:
    """Write ``cameras`` as an INRIA cameras.json (centre-of-image principal point)."""
    entries = []
    for i, camera in enumerate(cameras):
        c2w = camera.camera_to_world
        entries.append({"id": i, "img_name": camera.name or f"view_{i}",
                        "width": camera.width, "height": camera.height,
                        "position": c2w[:3, 3].tolist(), "rotation": c2w[:3, :3].tolist(),
                        "fx": camera.fx, "fy": camera.fy})
    path.write_text(json.dumps(entries))
    return path


def centre_pixel(scene, camera, label: int) -> tuple[float, float]:
    """Pixel (x, y) where the mean position of object ``label`` projects."""
    from csgs_codec.semantic.evaluation import object_click_points

    return object_click_points(scene.positions, scene.labels, camera)[label]


def background_pixel(camera) -> tuple[float, float]:
    """A pixel in the bottom-left corner, away from every object of :func:`five_objects`."""
    return 2.0, float(camera.height - 3)


def label_mask(labels: np.ndarray, label: int) -> np.ndarray:
    """(N,) bool, the elements of object ``label``."""
    return np.asarray(labels) == label
