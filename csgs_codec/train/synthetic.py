"""Seeded synthetic training data: scenes of labelled objects rendered with ground truth.

A scene is K objects, each a thin ellipsoidal shell of Gaussians of one base color (hues spread
around the color wheel, a little per-Gaussian jitter), placed around a circle in the z = 0
plane so that no two overlap; Gaussian labels are 1..K. Views are orbit cameras (+z up) around
it, rendered with the project's rasterizer into images and instance masks. A pixel's mask id is
the object with the largest accumulated weight (sum of alpha * T over its Gaussians, rendered as
a one-hot feature map), or 0 (background) where the final transmittance outweighs every object.
Everything depends only on the arguments (numpy's PCG64 generator).
"""

from __future__ import annotations

import colorsys
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import InputError
from csgs_codec.render.image_io import png_bytes
from csgs_codec.render.rasterizer import render
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.cameras_io import OPENGL_TO_OPENCV
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.scene.orbit import orbit_cameras
from csgs_codec.train.views import TrainingView

#: Degree-0 spherical harmonic constant: rgb = 0.5 + C0 * sh_dc.
SH_C0 = 0.28209479177387814
#: Objects are ellipsoidal shells this fraction of their radius thick (trained 3DGS scenes
#: put their Gaussians on surfaces, so most are seen from some view).
SHELL_THICKNESS = 0.15
#: Id of pixels no object covers, in synthetic masks.
BACKGROUND_ID = 0
#: File name of the ground-truth scene :meth:`SyntheticDataset.write` adds to the dataset.
GROUND_TRUTH_FILE = "scene.ply"


@dataclass
class SyntheticDataset:
    """A labelled scene and its rendered views.

    Attributes:
        scene: the Gaussians, ``labels`` (N,) int32 in 1..K.
        views: rendered :class:`TrainingView` s, masks (H, W) int32 in 0..K (0: background).
        object_count: K.
    """

    scene: GaussianScene
    views: list[TrainingView]
    object_count: int

    def write(self, folder: str | Path) -> Path:
        """Write the views as :func:`write_transforms_dataset` does, plus the ground-truth
        scene (with its ``label`` property) as ``scene.ply``; returns transforms.json's path.
        """
        from csgs_codec.interchange.ply_writer import write_ply

        target = write_transforms_dataset(self.views, folder)
        write_ply(self.scene, Path(folder) / GROUND_TRUTH_FILE)
        return target


def synthetic_scene(seed: int = 0, *, objects: int = 3, gaussians_per_object: int = 200
                    ) -> GaussianScene:
    """K labelled ellipsoidal shells of Gaussians (module notes); SH degree 0.

    Args:
        seed: the random seed; equal arguments give bit-identical scenes.
        objects: K >= 1.
        gaussians_per_object: Gaussians per object (>= 1).

    Returns:
        A :class:`GaussianScene` of K * gaussians_per_object Gaussians, labels 1..K.
    """
    if objects < 1 or gaussians_per_object < 1:
        raise InputError(f"need >= 1 object and Gaussian per object, got {objects}, "
                         f"{gaussians_per_object}", property="objects")
    rng = np.random.default_rng([seed, 9])
    # Objects sit on a circle whose radius leaves gaps of at least 0.2 between neighbours.
    max_radius = 0.35
    circle = 0.0 if objects == 1 else (2 * max_radius + 0.2) / (2 * math.sin(math.pi / objects))
    hue_offset = rng.uniform()
    parts = []
    for k in range(objects):
        angle = 2 * math.pi * k / objects + rng.uniform(-0.1, 0.1)
        centre = np.array([circle * math.cos(angle), circle * math.sin(angle),
                           rng.uniform(0.0, 0.2)])
        radii = rng.uniform(0.15, max_radius, size=3)
        directions = rng.standard_normal((gaussians_per_object, 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        depth = 1.0 - SHELL_THICKNESS * rng.uniform(size=(gaussians_per_object, 1))
        positions = centre + directions * depth * radii
        rgb = np.array(colorsys.hsv_to_rgb((hue_offset + k / objects) % 1.0, 0.8, 0.9))
        colors = np.clip(rgb + rng.normal(0, 0.03, size=(gaussians_per_object, 3)), 0, 1)
        # Sigma about half the spacing sqrt(4 pi r^2 / n) of n Gaussians on the shell.
        log_scale = np.log(1.8 * float(radii.min()) / math.sqrt(gaussians_per_object))
        scales = log_scale + rng.normal(0, 0.15, size=(gaussians_per_object, 3))
        rotations = rng.standard_normal((gaussians_per_object, 4))
        rotations /= np.linalg.norm(rotations, axis=1, keepdims=True)
        parts.append((positions, colors, scales, rotations,
                      rng.uniform(2.0, 4.0, size=gaussians_per_object),
                      np.full(gaussians_per_object, k + 1)))
    positions, colors, scales, rotations, opacity, labels = (
        np.concatenate(column) for column in zip(*parts))
    n = len(positions)
    return GaussianScene(
        positions=positions.astype(np.float32),
        sh_dc=((colors - 0.5) / SH_C0).astype(np.float32),
        sh_rest=np.zeros((n, 0, 3), np.float32),
        opacity=opacity.astype(np.float32),
        scales=scales.astype(np.float32),
        rotations=rotations.astype(np.float32),
        labels=labels.astype(np.int32),
    )


def instance_mask(scene: GaussianScene, camera: Camera, *, backend: str = "auto"
                  ) -> np.ndarray:
    """(H, W) int32 ground-truth ids: the label with the largest rendered weight, or
    :data:`BACKGROUND_ID` where the final transmittance is larger (labels must be >= 1).

    Raises:
        InputError: the scene has no labels or labels below 1.
    """
    if scene.labels is None or (len(scene) and int(scene.labels.min()) < 1):
        raise InputError("scene needs labels >= 1 to render an instance mask",
                         property="labels")
    count = int(scene.labels.max()) if len(scene) else 0
    one_hot = np.zeros((len(scene), max(count, 1)), np.float32)
    one_hot[np.arange(len(scene)), scene.labels - 1] = 1.0
    out = render(scene, camera, backend=backend, features=one_hot)
    weights = np.concatenate([(1.0 - out.alpha)[..., None], out.features[..., :count]], axis=2)
    return np.argmax(weights, axis=2).astype(np.int32)


def make_synthetic_dataset(seed: int = 0, *, objects: int = 3, gaussians_per_object: int = 200,
                           views: int = 8, width: int = 64, height: int = 48,
                           elevation_deg: float = 30.0, backend: str = "auto"
                           ) -> SyntheticDataset:
    """A :func:`synthetic_scene` rendered from ``views`` orbit cameras (+z up).

    Args:
        seed, objects, gaussians_per_object: as for :func:`synthetic_scene`.
        views: number of cameras (>= 1), evenly spaced in azimuth.
        width, height: image size in pixels.
        elevation_deg: camera elevation above the objects' plane, degrees.
        backend: rasterizer backend (see :func:`csgs_codec.render.rasterizer.render`).

    Returns:
        :class:`SyntheticDataset`; images are (H, W, 3) float32 clipped to [0, 1] on a black
        background, view names ``images/view_000.png`` ...
    """
    scene = synthetic_scene(seed, objects=objects, gaussians_per_object=gaussians_per_object)
    cameras = orbit_cameras(scene, views, width=width, height=height, up="+z",
                            elevation_deg=elevation_deg, fill=1.0)
    rendered = []
    for i, camera in enumerate(cameras):
        name = f"images/view_{i:03d}.png"
        camera = Camera(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy,
                        camera.world_to_camera, name=name)
        image = np.clip(render(scene, camera, backend=backend).image, 0.0, 1.0)
        rendered.append(TrainingView(image.astype(np.float32), camera,
                                     instance_mask(scene, camera, backend=backend), name=name))
    return SyntheticDataset(scene, rendered, objects)


def write_transforms_dataset(views: list[TrainingView], folder: str | Path) -> Path:
    """Write views as a nerfstudio-style dataset that :func:`load_dataset` reads back.

    Layout: ``transforms.json`` (per-frame ``w``, ``h``, ``fl_x``, ``fl_y``, ``cx``, ``cy`` and
    an OpenGL camera-to-world ``transform_matrix``; ``file_path`` is the view name, which must
    be a relative path ending in .png), the 8-bit PNG images at those paths, and
    ``masks/<stem>.png`` (8-bit grey when every id is in 0..255, else 16-bit; ids must be in
    0..65535) for views with a mask.

    Returns:
        The path of ``transforms.json``.

    Raises:
        InputError: a view name that is not a relative .png path, or mask ids out of range.
    """
    folder = Path(folder)
    frames = []
    for view in views:
        view.validate()
        relative = Path(view.name)
        if relative.is_absolute() or relative.suffix != ".png" or ".." in relative.parts:
            raise InputError("view name must be a relative path ending in .png",
                             file=view.name, property="name")
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        write_atomically(folder / relative, png_bytes(view.image))
        if view.mask is not None:
            (folder / "masks").mkdir(parents=True, exist_ok=True)
            write_atomically(folder / "masks" / f"{relative.stem}.png", _mask_png(view))
        camera = view.camera
        frames.append({
            "file_path": view.name, "w": camera.width, "h": camera.height,
            "fl_x": camera.fx, "fl_y": camera.fy, "cx": camera.cx, "cy": camera.cy,
            "transform_matrix": (camera.camera_to_world @ OPENGL_TO_OPENCV).tolist(),
        })
    target = folder / "transforms.json"
    write_atomically(target, json.dumps({"frames": frames}, indent=1).encode("utf-8"))
    return target


def _mask_png(view: TrainingView) -> bytes:
    import io

    from PIL import Image

    mask = view.mask
    if mask.size and (mask.min() < 0 or mask.max() > 65535):
        raise InputError("mask ids must be in 0..65535 to be written as PNG",
                         file=view.name, property="mask")
    buffer = io.BytesIO()
    pixels = mask.astype(np.uint8 if mask.size == 0 or mask.max() < 256 else np.uint16)
    Image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()
