"""Small synthetic Gaussian scenes for the render, metrics and CLI tests."""

from __future__ import annotations

import numpy as np

from csgs_codec.scene.gaussian_scene import GaussianScene

SH_C0 = 0.28209479177387814


def scene_from(positions, *, colors=None, log_scale=-2.0, opacity_logit=4.0, labels=None,
               sh_degree=0, seed=0) -> GaussianScene:
    """Isotropic Gaussians at ``positions`` (N, 3) with RGB ``colors`` (N, 3) in [0, 1]."""
    positions = np.asarray(positions, np.float32).reshape(-1, 3)
    n = len(positions)
    rng = np.random.default_rng(seed)
    if colors is None:
        colors = rng.uniform(0.3, 0.7, size=(n, 3))
    rest = {0: 0, 1: 3, 2: 8, 3: 15}[sh_degree]
    return GaussianScene(
        positions=positions,
        sh_dc=((np.asarray(colors, np.float64) - 0.5) / SH_C0).astype(np.float32),
        sh_rest=np.zeros((n, rest, 3), np.float32),
        opacity=np.full(n, opacity_logit, np.float32),
        scales=np.full((n, 3), log_scale, np.float32),
        rotations=np.tile(np.array([1, 0, 0, 0], np.float32), (n, 1)),
        labels=None if labels is None else np.asarray(labels, np.int32),
    )


def blob_scene(count: int = 400, seed: int = 0, **options) -> GaussianScene:
    """``count`` Gaussians spread in a unit ball at the origin, random mid-range colors."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    radii = rng.uniform(0, 1, size=(count, 1)) ** (1 / 3)
    positions = directions / np.linalg.norm(directions, axis=1, keepdims=True) * radii
    return scene_from(positions, seed=seed, **options)


def project(camera, points) -> np.ndarray:
    """(N, 2) pixel coordinates (u, v) of world ``points`` (N, 3) seen by ``camera``."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    cam = points @ camera.world_to_camera[:3, :3].T + camera.world_to_camera[:3, 3]
    return np.stack([camera.fx * cam[:, 0] / cam[:, 2] + camera.cx,
                     camera.fy * cam[:, 1] / cam[:, 2] + camera.cy], axis=1)
