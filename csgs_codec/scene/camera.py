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


#: Range of a focal length, in units of the image's longer side: 1e-2 is a field of view of
#: 178 degrees, 1e4 a lens 10,000 times longer than the sensor. Outside it, projections
#: overflow float32 (fl_x 1e-300) or nothing is visible.
FOCAL_RANGE = (1e-2, 1e4)
#: How far outside the image a principal point may lie, in image widths (heights).
PRINCIPAL_POINT_MARGIN = 10.0


def intrinsics_problem(width: int, height: int, fx: float, fy: float, cx: float, cy: float
                       ) -> tuple[str, str] | None:
    """(field, what is wrong) for pinhole intrinsics no render can use, or None when sane.

    Focal lengths (pixels) must lie in :data:`FOCAL_RANGE` times the longer image side, and
    the principal point (pixels) within :data:`PRINCIPAL_POINT_MARGIN` image sizes of the
    image. Fields are named "fx", "fy", "cx", "cy".
    """
    side = max(width, height)
    low, high = FOCAL_RANGE[0] * side, FOCAL_RANGE[1] * side
    for field, value in (("fx", fx), ("fy", fy)):
        if not low <= value <= high:
            return field, (f"focal length {value:g} px is out of range for a {width}x{height} "
                           f"image ({low:g}..{high:g} px)")
    for field, value, size in (("cx", cx, width), ("cy", cy, height)):
        margin = PRINCIPAL_POINT_MARGIN * size
        if not -margin <= value <= size + margin:
            return field, (f"principal point {value:g} px is too far outside the "
                           f"{width}x{height} image ({-margin:g}..{size + margin:g} px)")
    return None
