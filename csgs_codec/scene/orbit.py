"""Orbit cameras around a scene: the views used to score a scene that comes without cameras.

The orbit circles the scene's robust centre at a fixed elevation, far enough that the robust
extent fills a set fraction of the frame. "Robust" means the box between low and high
percentiles of the positions of the Gaussians that are not nearly transparent, so floaters far
from the subject move neither the centre nor the radius.

The up axis is guessed from conventions, since a 3DGS scene carries no gravity direction:

* when the scene is flat (its thinnest robust side is under half of the middle one: an object
  on a table, terrain, a room floor) the thin axis is up: +z when it is z or x (the CG and
  geographic z-up convention), -y when it is y (COLMAP captures are y-down);
* otherwise -y, because most captured scenes keep the first COLMAP camera's frame, whose
  y axis points down.

Callers that know better pass ``up`` ("+z", "-y", ... or a vector).
"""

from __future__ import annotations

import math

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.camera import DEFAULT_NEAR_PLANE, Camera
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Gaussians at or below this opacity are ignored when measuring the scene.
MIN_OPACITY_FOR_BOUNDS = 0.1
#: Orbit cameras closer than 1 world unit to the centre scale the near plane down with their
#: distance (near = this x distance), so a scene renders the same at any extent (a 1e-6 scene
#: would otherwise lie wholly inside the default near plane).
NEAR_PLANE_PER_DISTANCE = DEFAULT_NEAR_PLANE
_AXES = {"x": 0, "y": 1, "z": 2}


def parse_up(up: str | np.ndarray | tuple | list) -> np.ndarray:
    """Unit up vector (3,) float64 from "+x", "-y", "z", ... or any non-zero 3-vector."""
    if isinstance(up, str):
        text = up.strip().lower()
        sign = -1.0 if text.startswith("-") else 1.0
        axis = text.lstrip("+-")
        if axis not in _AXES:
            raise InputError(f"up axis must be one of +x -x +y -y +z -z, got {up!r}",
                             property="up")
        vector = np.zeros(3)
        vector[_AXES[axis]] = sign
        return vector
    vector = np.asarray(up, dtype=np.float64).reshape(-1)
    norm = float(np.linalg.norm(vector)) if vector.shape == (3,) else 0.0
    if not (math.isfinite(norm) and norm > 0):
        raise InputError(f"up must be a non-zero 3-vector, got {up!r}", property="up")
    return vector / norm


def robust_bounds(scene: GaussianScene, percentile: float = 2.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) (3,) float64 percentile box of the positions of the visible Gaussians.

    Gaussians with opacity <= :data:`MIN_OPACITY_FOR_BOUNDS` are left out unless that would
    leave fewer than 16.

    Raises:
        InputError: the scene has no Gaussians.
    """
    if len(scene) == 0:
        raise InputError("the scene has no Gaussians to frame")
    positions = scene.positions.astype(np.float64)
    with np.errstate(over="ignore"):  # exp(-logit) overflows to inf for logits below -709
        opacity = 1.0 / (1.0 + np.exp(-scene.opacity.astype(np.float64)))
    visible = positions[opacity > MIN_OPACITY_FOR_BOUNDS]
    if len(visible) >= 16:
        positions = visible
    return (np.percentile(positions, percentile, axis=0),
            np.percentile(positions, 100 - percentile, axis=0))


def guess_up_axis(scene: GaussianScene, percentile: float = 2.0) -> np.ndarray:
    """Up vector (3,) float64 by the conventions in the module notes."""
    low, high = robust_bounds(scene, percentile)
    sides = high - low
    order = np.argsort(sides)
    thinnest, middle = sides[order[0]], sides[order[1]]
    if middle > 0 and thinnest < 0.5 * middle:
        return parse_up("-y" if order[0] == 1 else "+z")
    return parse_up("-y")


def orbit_cameras(scene: GaussianScene, count: int = 16, *, width: int = 800,
                  height: int = 600, up: str | np.ndarray | None = None,
                  elevation_deg: float = 20.0, fov_y_deg: float = 40.0, fill: float = 0.7,
                  percentile: float = 2.0) -> list[Camera]:
    """``count`` cameras evenly spaced in azimuth around the scene, looking at its centre.

    Args:
        scene: the scene to frame.
        count: number of views (>= 1).
        width, height: image size in pixels.
        up: up direction ("+z", "-y", a 3-vector); guessed with :func:`guess_up_axis` if None.
        elevation_deg: camera height above the horizontal plane through the centre, degrees.
        fov_y_deg: vertical field of view, degrees (square pixels).
        fill: fraction of the smaller image side the robust extent spans.
        percentile: the robust box runs from this percentile to 100 minus it.

    Returns:
        ``count`` cameras named ``orbit_000`` ... in azimuth order, OpenCV convention.
    """
    if count < 1:
        raise InputError(f"orbit needs at least one view, got {count}", property="orbit")
    if width < 1 or height < 1:
        raise InputError(f"image size must be positive, got {width}x{height}", property="size")
    up_vector = guess_up_axis(scene, percentile) if up is None else parse_up(up)
    low, high = robust_bounds(scene, percentile)
    centre = (low + high) / 2
    extent = float(np.max(high - low))
    if not extent > 0:
        extent = 1.0  # a single point or a flat sheet seen edge-on: any distance shows it
    fy = 0.5 * height / math.tan(math.radians(fov_y_deg) / 2)
    half_fov_small = math.atan(0.5 * min(width, height) / fy)
    distance = 0.5 * extent / fill / math.tan(half_fov_small) + 0.5 * extent
    near_plane = min(DEFAULT_NEAR_PLANE, NEAR_PLANE_PER_DISTANCE * distance)
    first, second = _horizontal_basis(up_vector)
    elevation = math.radians(elevation_deg)
    cameras = []
    for i in range(count):
        azimuth = 2 * math.pi * i / count
        horizontal = math.cos(azimuth) * first + math.sin(azimuth) * second
        direction = math.cos(elevation) * horizontal + math.sin(elevation) * up_vector
        position = centre + distance * direction
        cameras.append(Camera(width, height, fy, fy, width / 2, height / 2,
                              look_at(position, centre, up_vector), name=f"orbit_{i:03d}",
                              near_plane=near_plane))
    return cameras


def look_at(position: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(4, 4) float64 world-to-camera matrix of an OpenCV camera at ``position`` facing
    ``target`` with ``up`` pointing up in the image (towards smaller pixel y)."""
    forward = np.asarray(target, np.float64) - np.asarray(position, np.float64)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-9:  # looking straight along up: any right will do
        right = np.cross(forward, _horizontal_basis(up)[0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rotation = np.stack([right, down, forward])  # rows: camera axes in world coordinates
    world_to_camera = np.eye(4)
    world_to_camera[:3, :3] = rotation
    world_to_camera[:3, 3] = -rotation @ np.asarray(position, np.float64)
    return world_to_camera


def _horizontal_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane normal to ``up``; the first comes from the world
    axis least aligned with up, so view 0 looks along a world axis when up is one."""
    seed = np.zeros(3)
    seed[int(np.argmin(np.abs(up)))] = 1.0
    first = seed - np.dot(seed, up) * up
    first /= np.linalg.norm(first)
    return first, np.cross(up, first)
