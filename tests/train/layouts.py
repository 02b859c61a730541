"""Write small datasets in the three camera layouts (transforms.json, INRIA, COLMAP) for tests."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from csgs_codec.render.image_io import save_png
from csgs_codec.train.views import TrainingView
from tests.colmap_model import ColmapCamera, ColmapImage, write_colmap_model


def rotation_to_quaternion(rotation: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a (3, 3) rotation matrix (Shepperd's method)."""
    m = np.asarray(rotation, dtype=np.float64)
    trace = np.trace(m)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, 0.0]
        q[0] = (m[k, j] - m[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (m[j, i] + m[i, j]) / s
        q[1 + k] = (m[k, i] + m[i, k]) / s
    q = np.asarray(q)
    return q / np.linalg.norm(q)


def save_images(views: list[TrainingView], folder: Path, names: list[str]) -> None:
    """PNG images ``folder/name`` for each view."""
    folder.mkdir(parents=True, exist_ok=True)
    for view, name in zip(views, names):
        save_png(view.image, folder / name)


def write_inria(views: list[TrainingView], root: Path) -> Path:
    """``root/cameras.json`` + ``root/images/view_XXX.png``; returns root."""
    names = [f"view_{i:03d}" for i in range(len(views))]
    save_images(views, root / "images", [f"{n}.png" for n in names])
    entries = []
    for i, (view, name) in enumerate(zip(views, names)):
        c2w = view.camera.camera_to_world
        entries.append({"id": i, "img_name": name, "width": view.camera.width,
                        "height": view.camera.height, "position": c2w[:3, 3].tolist(),
                        "rotation": c2w[:3, :3].tolist(), "fx": view.camera.fx,
                        "fy": view.camera.fy})
    (root / "cameras.json").write_text(json.dumps(entries))
    return root


def write_colmap(views: list[TrainingView], root: Path, *, binary: bool) -> Path:
    """``root/sparse/0/{cameras,images}.{txt,bin}`` + ``root/images``; returns root."""
    names = [f"view_{i:03d}.png" for i in range(len(views))]
    save_images(views, root / "images", names)
    model = root / "sparse" / "0"
    cameras, images = [], []
    for i, (view, name) in enumerate(zip(views, names), start=1):
        c = view.camera
        w2c = c.world_to_camera
        cameras.append(ColmapCamera(i, "PINHOLE", c.width, c.height, (c.fx, c.fy, c.cx, c.cy)))
        images.append(ColmapImage(i, tuple(rotation_to_quaternion(w2c[:3, :3]).tolist()),
                                  tuple(w2c[:3, 3].tolist()), i, name))
    write_colmap_model(model, cameras, images, binary=binary)
    return root
