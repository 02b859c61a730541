"""Builders shared by the rasterizer tests: cameras and small scenes (no tests here)."""

from __future__ import annotations

import numpy as np

from csgs_codec.render.sh import SH_C0
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene


def camera_at_origin(width: int = 33, height: int = 25, focal: float = 40.0) -> Camera:
    """Identity-pose camera whose principal point is the centre of the middle pixel."""
    return Camera(width, height, focal, focal, width // 2 + 0.5, height // 2 + 0.5, np.eye(4))


def look_at_camera(eye: np.ndarray, target: np.ndarray, up: np.ndarray, width: int,
                   height: int, fov_deg: float = 50.0) -> Camera:
    """OpenCV camera at ``eye`` looking at ``target`` with ``up`` up on screen."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rot = np.stack([right, down, forward])
    w2c = np.eye(4)
    w2c[:3, :3] = rot
    w2c[:3, 3] = -rot @ eye
    focal = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    return Camera(width, height, focal, focal, width / 2, height / 2, w2c)


def gaussians(positions, colors, log_scale, opacity_logit) -> GaussianScene:
    """Isotropic, degree-0 Gaussians with the given RGB colors (color = 0.5 + C0 * dc)."""
    pos = np.asarray(positions, np.float32).reshape(-1, 3)
    n = len(pos)
    col = np.asarray(colors, np.float32).reshape(n, 3)
    return GaussianScene(
        positions=pos,
        sh_dc=((col - 0.5) / SH_C0).astype(np.float32),
        sh_rest=np.zeros((n, 0, 3), np.float32),
        opacity=np.broadcast_to(np.float32(opacity_logit), (n,)).astype(np.float32),
        scales=np.full((n, 3), log_scale, np.float32),
        rotations=np.tile(np.array([1, 0, 0, 0], np.float32), (n, 1)),
    )


def orbit_view(scene: GaussianScene, up: np.ndarray, width: int, height: int,
               azimuth_deg: float = 0.0, distance: float = 1.5) -> Camera:
    """A camera on a circle around the scene's robust centre, slightly above it."""
    centre, extent = scene.robust_center_and_extent()
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    side = np.cross(up, [0.3, 0.5, 0.8])
    side /= np.linalg.norm(side)
    other = np.cross(up, side)
    a = np.radians(azimuth_deg)
    eye = centre + distance * extent * (np.cos(a) * side + np.sin(a) * other) + 0.4 * extent * up
    return look_at_camera(eye, centre, up, width, height)
