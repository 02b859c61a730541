"""Front door of the rasterizer: render a :class:`GaussianScene` from a :class:`Camera`.

Backends (all follow the rule in :mod:`csgs_codec.render.composite_torch`):

- ``"torch"``: the differentiable reference (:func:`rasterize_gaussians`).
- ``"numba"``: the fast CPU forward path; needs the optional numba extra.
- ``"gsplat"``: CUDA through gsplat; needs a GPU and gsplat.
- ``"auto"``: gsplat when usable, else numba when installed, else torch.

For training, call :func:`csgs_codec.render.rasterize_torch.rasterize_gaussians` on tensors.
"""

from __future__ import annotations

import warnings

import numpy as np
import torch

from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.rasterize_gsplat import gsplat_available, rasterize_gsplat
from csgs_codec.render.rasterize_numba import rasterize_numba
from csgs_codec.render.rasterize_torch import prepare_gaussians, rasterize_gaussians
from csgs_codec.render.render_output import RenderOutput
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Backend names :func:`render` accepts.
BACKENDS = ("auto", "torch", "numba", "gsplat")
#: Largest image :func:`render` makes, in pixels (guards against absurd camera sizes).
MAX_PIXELS = 1 << 26


def scene_tensors(scene: GaussianScene, dtype: torch.dtype = torch.float32,
                  device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
    """The scene's raw attributes as tensors named after :func:`rasterize_gaussians` arguments.

    Returns:
        {"means": [N, 3], "log_scales": [N, 3], "quats": [N, 4], "opacity_logits": [N],
        "sh": [N, 1 + B, 3]} (DC first, then ``sh_rest``).
    """
    def t(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.ascontiguousarray(a), dtype=dtype, device=device)

    return {
        "means": t(scene.positions),
        "log_scales": t(scene.scales),
        "quats": t(scene.rotations),
        "opacity_logits": t(scene.opacity),
        "sh": torch.cat([t(scene.sh_dc)[:, None, :], t(scene.sh_rest)], dim=1),
    }


def resolve_backend(backend: str) -> str:
    """The backend that ``backend`` names on this machine ("auto" picks the fastest usable).

    A requested backend that is not installed falls back (numba -> torch, gsplat -> numba or
    torch) with a :class:`CsgsWarning` saying why.
    """
    if backend not in BACKENDS:
        raise InputError(f"unknown backend {backend!r}; expected one of {BACKENDS}",
                         property="backend")
    if backend == "auto":
        if gsplat_available():
            return "gsplat"
        return "numba" if numba_available() else "torch"
    if backend == "gsplat" and not gsplat_available():
        fallback = "numba" if numba_available() else "torch"
        warnings.warn(f"gsplat backend unavailable (needs a CUDA GPU and gsplat); using "
                      f"{fallback}", CsgsWarning, stacklevel=3)
        return fallback
    if backend == "numba" and not numba_available():
        warnings.warn("numba is not installed (pip install 'csgs[fast]'); using the slower "
                      "torch backend", CsgsWarning, stacklevel=3)
        return "torch"
    return backend


def check_render_inputs(scene: GaussianScene, camera: Camera, features: np.ndarray | None,
                        background: tuple[float, float, float]) -> None:
    """Raise :class:`InputError` naming what is wrong with a render's inputs: camera size,
    intrinsics, near plane and pose, the background, the scene's values, ``features``
    ((N, F) finite, or None)."""
    if not (isinstance(camera.width, int | np.integer) and isinstance(camera.height,
                                                                      int | np.integer)):
        raise InputError("camera width and height must be integers", property="camera")
    if camera.width <= 0 or camera.height <= 0 or camera.width * camera.height > MAX_PIXELS:
        raise InputError(f"camera size {camera.width}x{camera.height} outside 1..{MAX_PIXELS} "
                         "pixels", property="camera")
    intrinsics = np.array([camera.fx, camera.fy, camera.cx, camera.cy], dtype=np.float64)
    if not np.all(np.isfinite(intrinsics)) or camera.fx <= 0 or camera.fy <= 0:
        raise InputError("camera intrinsics must be finite with fx, fy > 0", property="camera")
    if not (np.isfinite(camera.near_plane) and camera.near_plane > 0):
        raise InputError(f"camera near plane must be finite and > 0, got {camera.near_plane}",
                         property="camera")
    w2c = np.asarray(camera.world_to_camera)
    if w2c.shape != (4, 4) or not np.all(np.isfinite(w2c)):
        raise InputError("world_to_camera must be a finite 4x4 matrix", property="camera")
    bg = np.asarray(background, dtype=np.float64)
    if bg.shape != (3,) or not np.all(np.isfinite(bg)):
        raise InputError("background must be three finite numbers", property="background")
    scene.validate()
    if features is not None:
        f = np.asarray(features)
        if f.ndim != 2 or f.shape[0] != len(scene) or not np.all(np.isfinite(f)):
            raise InputError(f"features must be finite (N, F) with N = {len(scene)}, got "
                             f"{f.shape}", property="features")


def render(scene: GaussianScene, camera: Camera, *,
           background: tuple[float, float, float] = (0.0, 0.0, 0.0), backend: str = "auto",
           features: np.ndarray | None = None) -> RenderOutput:
    """Render one view of a scene.

    Args:
        scene: the Gaussians (raw INRIA attributes; SH of any degree 0..3).
        camera: pinhole camera; the image is camera.height x camera.width; Gaussians whose
            camera-space z is at most ``camera.near_plane`` are culled.
        background: linear RGB behind the scene (black by default).
        backend: "auto", "torch", "numba" or "gsplat" (see the module docstring).
        features: optional (N, F) per-Gaussian features (e.g. ``scene.semantic``) to render
            into ``RenderOutput.features``.

    Returns:
        :class:`RenderOutput`: image (H, W, 3), alpha (H, W), depth (H, W), features
        (H, W, F) or None, all float32, and the backend actually used.

    Raises:
        InputError: bad camera, background, features, backend name or scene values.
    """
    check_render_inputs(scene, camera, features, background)
    chosen = resolve_backend(backend)
    tensors = scene_tensors(scene)
    feats = None if features is None else torch.as_tensor(np.asarray(features, np.float32),
                                                         device=tensors["means"].device)
    if chosen == "gsplat":
        return rasterize_gsplat(**tensors, camera=camera, features=feats,
                                background=background, near_plane=camera.near_plane)
    with torch.no_grad():
        if chosen == "numba":
            prepared = prepare_gaussians(tensors["means"], tensors["log_scales"],
                                         tensors["quats"], tensors["opacity_logits"], camera,
                                         sh=tensors["sh"], near_plane=camera.near_plane)
            return rasterize_numba(prepared, camera, features=None if feats is None
                                   else feats.numpy(), background=background)
        out = rasterize_gaussians(**tensors, camera=camera, features=feats,
                                  background=background, near_plane=camera.near_plane)
    return RenderOutput(out.image.numpy(), out.alpha.numpy(), out.depth.numpy(),
                        None if out.features is None else out.features.numpy(), "torch")
