"""Pinhole camera model shared by the renderer, camera loaders and metrics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Largest camera file (cameras.json, transforms.json, COLMAP) read into memory (bytes); real
#: ones are a few MB at most.
MAX_CAMERA_FILE_BYTES = 256 * 1024 * 1024
#: Largest image side accepted from a camera file (pixels).
MAX_IMAGE_SIDE = 1 << 16
#: Near plane in camera-space z (world units) of a camera that does not set one: Gaussians
#: closer are culled.
DEFAULT_NEAR_PLANE = 0.01


@dataclass(frozen=True)
class Camera:
    """A pinhole camera, OpenCV convention (x right, y down, z forward, looking along +z).

    Attributes:
        width: image width in pixels.
        height: image height in pixels.
        fx, fy: focal lengths in pixels.
        cx, cy: principal point in pixels (pixel centres at integer + 0.5).
        world_to_camera: (4, 4) float64 rigid transform taking world points to camera space.
        name: optional identifier (e.g. the image file name).
        near_plane: camera-space z (world units, > 0) at or below which Gaussians are culled.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    world_to_camera: np.ndarray
    name: str = ""
    near_plane: float = DEFAULT_NEAR_PLANE

    @property
    def camera_to_world(self) -> np.ndarray:
        """(4, 4) float64 inverse of :attr:`world_to_camera`."""
        return np.linalg.inv(self.world_to_camera)

    @property
    def position(self) -> np.ndarray:
        """Camera centre in world coordinates, (3,) float64."""
        return self.camera_to_world[:3, 3].copy()
