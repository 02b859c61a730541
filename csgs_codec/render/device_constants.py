"""A camera's matrices and a background color as tensors on a device, made once each.

Training renders the same few cameras thousands of times; on a GPU every ``torch.as_tensor``
of a camera's numpy matrices is a copy from pageable host memory, which waits for the device
(measured on an H100: about 7 such copies in each 19 ms stage-1 step). :func:`camera_tensors`
keeps the tensors of the most recent cameras, keyed by the camera object itself (cameras are
frozen dataclasses; their arrays are not written after construction).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache

import torch

from csgs_codec.scene.camera import Camera

#: Camera-device pairs kept (more than any training set's views is not needed: the cache only
#: saves copies, and a miss makes the tensors again).
CACHE_SIZE = 1024


@dataclass(frozen=True)
class CameraTensors:
    """One camera's matrices on one device, float32.

    Attributes:
        world_to_camera: [4, 4] rigid transform.
        intrinsics: [3, 3] pinhole matrix (fx, fy, cx, cy).
        position: [3] camera centre, world units.
    """

    world_to_camera: torch.Tensor
    intrinsics: torch.Tensor
    position: torch.Tensor


_cache: OrderedDict[tuple[int, str], tuple[Camera, CameraTensors]] = OrderedDict()


def camera_tensors(camera: Camera, device: torch.device | str) -> CameraTensors:
    """``camera``'s :class:`CameraTensors` on ``device`` (cached; do not write to them)."""
    device = torch.device(device)
    key = (id(camera), str(device))
    hit = _cache.get(key)
    if hit is not None and hit[0] is camera:  # the cache holds the camera: ids stay unique
        _cache.move_to_end(key)
        return hit[1]
    tensors = CameraTensors(
        torch.as_tensor(camera.world_to_camera, dtype=torch.float32, device=device),
        torch.tensor([[camera.fx, 0.0, camera.cx], [0.0, camera.fy, camera.cy],
                      [0.0, 0.0, 1.0]], dtype=torch.float32, device=device),
        torch.as_tensor(camera.position, dtype=torch.float32, device=device))
    _cache[key] = (camera, tensors)
    if len(_cache) > CACHE_SIZE:
        _cache.popitem(last=False)
    return tensors


def background_tensor(background: torch.Tensor | tuple[float, float, float] | None,
                      device: torch.device | str) -> torch.Tensor:
    """[3] float32 RGB on ``device`` (black for None; a tensor is moved there as it is;
    tuples are cached: do not write to the result)."""
    if torch.is_tensor(background):
        return background.to(dtype=torch.float32, device=device)
    rgb = (0.0, 0.0, 0.0) if background is None else tuple(float(v) for v in background)
    return _background(rgb, str(torch.device(device)))


@lru_cache(maxsize=64)
def _background(rgb: tuple[float, ...], device: str) -> torch.Tensor:
    return torch.tensor(rgb, dtype=torch.float32, device=device)
