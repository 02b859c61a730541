"""Labelled synthetic scenes for click-selection tests and benchmarks: separate blobs, each with
its own unit semantic direction plus noise, and a camera looking down on them."""

from __future__ import annotations

import math

import numpy as np

from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import SH_REST_COUNTS, GaussianScene
from csgs_codec.scene.orbit import look_at

#: Degree-0 spherical harmonic constant: rgb = 0.5 + C0 * sh_dc.
SH_C0 = 0.28209479177387814


def semantic_directions(count: int, dim: int, rng: np.random.Generator) -> np.ndarray:
    """(count, dim) float64 unit directions, orthonormal when count <= dim."""
    directions = rng.standard_normal((max(count, dim), dim))
    if count <= dim:
        directions = np.linalg.qr(directions.T)[0].T
    directions = directions[:count]
    return directions / np.linalg.norm(directions, axis=1, keepdims=True)


def labelled_blob_scene(n_objects: int = 5, per_object: int = 400, *, semantic_dim: int = 6,
                        semantic_noise: float = 0.05, sh_degree: int = 0, radius: float = 0.3,
                        spacing: float = 1.0, seed: int = 0) -> GaussianScene:
    """``n_objects`` ellipsoidal blobs of Gaussians in the z = 0 plane, labelled 0..n-1.

    Args:
        n_objects: number of objects, laid out on a grid ``spacing`` apart (world units).
        per_object: Gaussians per object.
        semantic_dim: S, channels of the semantic feature (named ``ins_feat_*``).
        semantic_noise: standard deviation of the per-channel noise added to each object's
            unit semantic direction.
        sh_degree: SH degree stored; bands above 0 hold small random coefficients.
        radius: blob radius, world units.
        seed: everything is a function of the arguments.

    Returns:
        a scene with ``semantic`` (N, S) float32 and ``labels`` (N,) int32, objects in order.
    """
    rng = np.random.default_rng([seed, 8])
    side = int(math.ceil(math.sqrt(n_objects)))
    centres = np.array([[(i % side) * spacing, (i // side) * spacing, 0.0]
                        for i in range(n_objects)])
    n = n_objects * per_object
    labels = np.repeat(np.arange(n_objects, dtype=np.int32), per_object)
    direction = rng.standard_normal((n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    r = radius * rng.uniform(0, 1, (n, 1)) ** (1 / 3)
    positions = centres[labels] + direction * r * np.array([1.0, 0.8, 0.5])
    base_colors = rng.uniform(0.2, 0.8, (n_objects, 3))
    colors = np.clip(base_colors[labels] + 0.05 * rng.standard_normal((n, 3)), 0.02, 0.98)
    semantic = (semantic_directions(n_objects, semantic_dim, rng)[labels]
                + semantic_noise * rng.standard_normal((n, semantic_dim)))
    quats = rng.standard_normal((n, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    return GaussianScene(
        positions=positions.astype(np.float32),
        sh_dc=((colors - 0.5) / SH_C0).astype(np.float32),
        sh_rest=(0.05 * rng.standard_normal((n, SH_REST_COUNTS[sh_degree], 3))
                 ).astype(np.float32),
        opacity=rng.normal(2.0, 0.5, n).astype(np.float32),
        scales=(np.log(0.25 * radius) + 0.2 * rng.standard_normal((n, 3))).astype(np.float32),
        rotations=quats.astype(np.float32),
        semantic=semantic.astype(np.float32),
        semantic_names=tuple(f"ins_feat_{i}" for i in range(semantic_dim)),
        labels=labels)


def overview_camera(positions: np.ndarray, *, width: int = 320, height: int = 240,
                    fov_y_deg: float = 40.0, fill: float = 0.8, tilt: float = 0.3) -> Camera:
    """A camera above the z = 0 plane looking down at ``positions`` ((N, 3), world units),
    slightly tilted (``tilt`` of y per unit of height) so +y points up in the image; the
    points' x-y extent spans ``fill`` of the smaller image side."""
    positions = np.asarray(positions, np.float64)
    low, high = positions.min(axis=0), positions.max(axis=0)
    centre = (low + high) / 2
    extent = max(float(np.max(high[:2] - low[:2])), 1e-6)
    fy = 0.5 * height / math.tan(math.radians(fov_y_deg) / 2)
    distance = 0.5 * extent / fill * fy / (0.5 * min(width, height)) + high[2] - centre[2]
    offset = np.array([0.0, -tilt, 1.0])
    position = centre + distance * offset / np.linalg.norm(offset)
    return Camera(width, height, fy, fy, width / 2, height / 2,
                  look_at(position, centre, np.array([0.0, 1.0, 0.0])), name="overview")
