"""Viewing distributions: the cameras a scene is expected to be seen from.

The encoder spends precision where these views see it (:mod:`csgs_codec.render.sensitivity`).
Two sources:

* the scene's own cameras (``--cameras FILE``, or an INRIA output folder's cameras.json): the
  views it was captured and trained from, which is where a walk-through scene (a room, a
  street, seen from inside) is looked at;
* without cameras, :func:`default_distribution`, for objects looked at from outside: views on
  a sphere around the scene's robust centre at three distances (0.65, 1 and 1.5 times the
  distance at which the robust extent fills 70% of a 40-degree frame), every direction
  (Fibonacci sphere), each looking at the centre. It covers the usual ways an object is
  inspected (orbits at any elevation, closer and farther) without favouring one.

A scene walked through from inside must be given its cameras: views from outside would rank
its inner surfaces as unseen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.camera import DEFAULT_NEAR_PLANE, Camera
from csgs_codec.scene.cameras_io import resize_camera
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.scene.orbit import (
    NEAR_PLANE_PER_DISTANCE,
    guess_up_axis,
    look_at,
    parse_up,
    robust_bounds,
)

#: Distances of the default distribution's shells, as multiples of the framing distance.
DEFAULT_DISTANCES = (0.65, 1.0, 1.5)
#: Directions per shell of the default distribution.
DEFAULT_DIRECTIONS = 16
#: Image size of the default distribution's views (pixels): the size scenes are scored and
#: commonly viewed at. Sub-pixel Gaussians that vanish at 400x300 are detail at 800x600: on
#: plant, pruning allocated at 400x300 cost 1.7 dB of held-out PSNR at 800x600 (0.16 dB when
#: allocated at 800x600).
DEFAULT_SIZE = (800, 600)
#: Field of view (vertical, degrees) and the fraction of the frame the robust extent fills at
#: distance 1, as for the orbit views.
_FOV_Y_DEG = 40.0
_FILL = 0.7


@dataclass(frozen=True)
class ViewDistribution:
    """The cameras precision is allocated for, and where they came from.

    Attributes:
        cameras: the views.
        source: "default-sphere" or "cameras" (a camera file or an INRIA folder).
        description: one line for reports (e.g. ``72 views on a sphere at 3 distances``).
    """

    cameras: list[Camera]
    source: str
    description: str


def framing_distance(scene: GaussianScene, width: int, height: int,
                     fov_y_deg: float = _FOV_Y_DEG, fill: float = _FILL) -> float:
    """Distance (world units) from the robust centre at which the robust extent spans
    ``fill`` of the smaller image side; the orbit views' distance."""
    low, high = robust_bounds(scene)
    extent = float(np.max(high - low))
    if not extent > 0:
        extent = 1.0
    fy = 0.5 * height / math.tan(math.radians(fov_y_deg) / 2)
    half_fov_small = math.atan(0.5 * min(width, height) / fy)
    return 0.5 * extent / fill / math.tan(half_fov_small) + 0.5 * extent


def sphere_directions(count: int) -> np.ndarray:
    """(count, 3) float64 unit vectors spread evenly over the sphere (Fibonacci lattice)."""
    i = np.arange(count, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * i / count
    radius = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([radius * np.cos(phi), radius * np.sin(phi), z], axis=1)


def default_distribution(scene: GaussianScene, *, directions: int = DEFAULT_DIRECTIONS,
                         distances: tuple[float, ...] = DEFAULT_DISTANCES,
                         size: tuple[int, int] | None = None,
                         up: str | np.ndarray | None = None) -> ViewDistribution:
    """Views on a sphere around ``scene`` (see the module notes): ``directions`` per shell,
    shells at ``distances`` x the framing distance, images of ``size`` (width, height;
    default :data:`DEFAULT_SIZE`).

    Raises:
        InputError: an empty scene, no directions or distances, or a non-positive size.
    """
    if directions < 1 or not distances or min(distances) <= 0:
        raise InputError("a view distribution needs directions and positive distances")
    width, height = DEFAULT_SIZE if size is None else size
    if width < 1 or height < 1:
        raise InputError(f"image size must be positive, got {width}x{height}", property="size")
    up_vector = guess_up_axis(scene) if up is None else parse_up(up)
    low, high = robust_bounds(scene)
    centre = (low + high) / 2
    base = framing_distance(scene, width, height)
    fy = 0.5 * height / math.tan(math.radians(_FOV_Y_DEG) / 2)
    cameras = []
    for shell, factor in enumerate(distances):
        distance = base * factor
        near = min(DEFAULT_NEAR_PLANE, NEAR_PLANE_PER_DISTANCE * distance)
        # Each shell turns the lattice a little so shells do not share directions.
        turn = 2.0 * math.pi * shell / (len(distances) * directions)
        for j, d in enumerate(sphere_directions(directions)):
            c, s = math.cos(turn), math.sin(turn)
            d = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]])
            position = centre + distance * d
            cameras.append(Camera(width, height, fy, fy, width / 2, height / 2,
                                  look_at(position, centre, up_vector),
                                  name=f"sphere_{shell}_{j:03d}", near_plane=near))
    return ViewDistribution(cameras, "default-sphere",
                            f"{len(cameras)} views on a sphere at {len(distances)} distances")


#: Most cameras of a camera file the sensitivity pass renders (evenly spaced), and the
#: largest image side it renders them at: capture cameras run to hundreds of 4K frames.
MAX_CAMERAS = 96
MAX_SIDE = 800


def camera_distribution(cameras: list[Camera], origin: str) -> ViewDistribution:
    """The distribution of a scene's own cameras (``origin``: where they came from): at
    most :data:`MAX_CAMERAS` of them, evenly spaced, scaled to at most :data:`MAX_SIDE`
    pixels a side (the weights' relative sizes do not depend on the resolution)."""
    if not cameras:
        raise InputError("the camera file holds no cameras", file=origin)
    picks = np.unique(np.linspace(0, len(cameras) - 1, min(len(cameras), MAX_CAMERAS))
                      .round().astype(int))
    chosen = []
    for i in picks:
        camera = cameras[int(i)]
        scale = min(1.0, MAX_SIDE / max(camera.width, camera.height))
        if scale < 1.0:
            camera = resize_camera(camera, max(1, round(camera.width * scale)),
                                   max(1, round(camera.height * scale)))
        chosen.append(camera)
    return ViewDistribution(chosen, "cameras",
                            f"{len(chosen)} of {len(cameras)} cameras from {origin}")
