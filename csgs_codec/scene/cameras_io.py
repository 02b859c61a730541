"""Loading cameras from the files trainers write: INRIA cameras.json, transforms.json, COLMAP.

Every loader returns a list of :class:`~csgs_codec.scene.camera.Camera` in the OpenCV
convention (x right, y down, z forward) with ``world_to_camera`` as a (4, 4) float64 matrix.
Every malformed file raises :class:`InputError` naming the file and the field at fault.

Formats:

* INRIA ``cameras.json`` (written by the 3DGS trainer): a list of objects with ``width``,
  ``height``, ``fx``, ``fy``, ``position`` (camera centre, world) and ``rotation`` (3x3
  camera-to-world rotation, OpenCV axes). The principal point is the image centre.
* nerfstudio / instant-ngp ``transforms.json``: ``frames`` with a 4x4 camera-to-world
  ``transform_matrix`` in the OpenGL convention (x right, y up, z backward), converted here by
  flipping the camera's y and z axes. Intrinsics come from ``fl_x``/``fl_y`` or
  ``camera_angle_x``/``camera_angle_y``, ``cx``/``cy`` (default: image centre) and ``w``/``h``,
  at the top level or per frame (per-frame values win); without ``w``/``h`` (Blender-style
  files) the size is read from the frame's image, ``file_path`` relative to the JSON file,
  ``.png`` appended when it has no suffix. Lens distortion is ignored (warned).
* COLMAP text or binary models (``cameras`` + ``images``): see :mod:`.colmap_io`.
* LLFF captures (``poses_bounds.npy`` + ``images/``): see :mod:`.llff_io`.
"""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np

from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.scene.camera import (
    MAX_CAMERA_FILE_BYTES,
    MAX_IMAGE_SIDE,
    Camera,
    intrinsics_problem,
)
from csgs_codec.scene.colmap_io import is_colmap_path, load_colmap_cameras
from csgs_codec.scene.llff_io import is_llff_path, load_llff_capture
from csgs_codec.untrusted import load_json, open_regular, read_regular, refuse_non_regular

#: OpenGL camera axes (x right, y up, z back) to OpenCV (x right, y down, z forward).
OPENGL_TO_OPENCV = np.diag([1.0, -1.0, -1.0, 1.0])
_DISTORTION_KEYS = ("k1", "k2", "k3", "k4", "p1", "p2")


def load_cameras(path: str | Path) -> list[Camera]:
    """Load every camera in ``path``, recognising the format from its name and content.

    ``path`` may be an INRIA ``cameras.json``, a ``transforms*.json``, a COLMAP model folder
    (holding ``cameras.txt``/``images.txt`` or ``.bin``, directly or under ``sparse/0``) or one
    of the COLMAP files themselves, or an LLFF capture (its folder or ``poses_bounds.npy``;
    the cameras of its full-size images).

    Raises:
        InputError: unreadable file, unknown format or a malformed field (named).
    """
    path = Path(path)
    if "\0" not in str(path) and not path.exists():
        raise InputError("no such file or folder", file=path)
    refuse_non_regular(path, directory_ok=True)  # a NUL byte, a device or FIFO: refused
    if is_colmap_path(path):
        return load_colmap_cameras(path)
    if is_llff_path(path):
        return load_llff_capture(path).cameras
    if path.is_dir():
        raise InputError("folder holds no COLMAP model (cameras.txt/.bin + images.txt/.bin) "
                         "nor an LLFF poses_bounds.npy", file=path)
    document = _read_json(path)
    if isinstance(document, list):
        return cameras_from_inria_json(document, source=path)
    if isinstance(document, dict) and "frames" in document:
        return cameras_from_transforms_json(document, source=path)
    raise InputError("not a camera file: expected an INRIA cameras.json list or a "
                     "transforms.json object with 'frames'", file=path)


def cameras_from_inria_json(entries: list, *, source: str | Path | None = None
                            ) -> list[Camera]:
    """Cameras from the parsed content of an INRIA ``cameras.json`` (a list of dicts)."""
    cameras = []
    for i, entry in enumerate(entries):
        where = f"[{i}]"
        if not isinstance(entry, dict):
            raise InputError("camera entry is not an object", file=source, property=where)
        width = _image_side(entry, "width", source, where)
        height = _image_side(entry, "height", source, where)
        fx = _positive(entry, "fx", source, where)
        fy = _positive(entry, "fy", source, where)
        _check_intrinsics(width, height, (fx, fy, width / 2, height / 2),
                          ("fx", "fy", "width", "height"), source, where)
        position = _float_array(entry, "position", (3,), source, where)
        rotation = _float_array(entry, "rotation", (3, 3), source, where)
        _check_rotation(rotation, source, f"{where}.rotation")
        camera_to_world = np.eye(4)
        camera_to_world[:3, :3] = rotation
        camera_to_world[:3, 3] = position
        cameras.append(Camera(width, height, fx, fy, width / 2, height / 2,
                              rigid_inverse(camera_to_world),
                              name=str(entry.get("img_name", entry.get("id", i)))))
    if not cameras:
        raise InputError("no cameras in file", file=source)
    return cameras


def cameras_from_transforms_json(document: dict, *, source: str | Path | None = None
                                 ) -> list[Camera]:
    """Cameras from the parsed content of a nerfstudio / instant-ngp ``transforms.json``."""
    frames = document.get("frames")
    if not isinstance(frames, list) or not frames:
        raise InputError("'frames' must be a non-empty list", file=source, property="frames")
    cameras = []
    distorted = False
    for i, frame in enumerate(frames):
        where = f"frames[{i}]"
        if not isinstance(frame, dict):
            raise InputError("frame is not an object", file=source, property=where)
        merged = {**document, **frame}
        if ("w" not in merged or "h" not in merged) and source is not None:
            merged.update(_size_from_image_file(Path(source).parent, frame.get("file_path")))
        width = _image_side(merged, "w", source, where)
        height = _image_side(merged, "h", source, where)
        fx, fy = _transforms_focals(merged, width, height, source, where)
        cx = _finite(merged, "cx", source, where) if "cx" in merged else width / 2
        cy = _finite(merged, "cy", source, where) if "cy" in merged else height / 2
        focal_names = ("fl_x" if "fl_x" in merged else "camera_angle_x",
                       "fl_y" if "fl_y" in merged else "camera_angle_y")
        _check_intrinsics(width, height, (fx, fy, cx, cy), (*focal_names, "cx", "cy"), source,
                          where)
        distorted |= any(_nonzero_number(merged.get(k)) for k in _DISTORTION_KEYS)
        distorted |= "FISHEYE" in str(merged.get("camera_model", "")).upper()
        camera_to_world = _float_array(frame, "transform_matrix", (4, 4), source, where,
                                       allow_rows=3)
        _check_rotation(camera_to_world[:3, :3], source, f"{where}.transform_matrix")
        camera_to_world = camera_to_world @ OPENGL_TO_OPENCV
        cameras.append(Camera(width, height, fx, fy, cx, cy, rigid_inverse(camera_to_world),
                              name=str(frame.get("file_path", i))))
    if distorted:
        warnings.warn(f"{source}: lens distortion / fisheye model ignored; cameras are treated "
                      "as pinhole", CsgsWarning, stacklevel=2)
    return cameras


def resize_camera(camera: Camera, width: int, height: int) -> Camera:
    """The same camera rendering ``width`` x ``height`` pixels: intrinsics scaled per axis."""
    if width <= 0 or height <= 0:
        raise InputError(f"image size must be positive, got {width}x{height}")
    sx, sy = width / camera.width, height / camera.height
    return Camera(width, height, camera.fx * sx, camera.fy * sy, camera.cx * sx,
                  camera.cy * sy, camera.world_to_camera, name=camera.name)


def rigid_inverse(transform: np.ndarray) -> np.ndarray:
    """Inverse of a (4, 4) rotation + translation matrix, float64."""
    rotation = np.asarray(transform, dtype=np.float64)[:3, :3]
    inverse = np.eye(4)
    inverse[:3, :3] = rotation.T
    inverse[:3, 3] = -rotation.T @ np.asarray(transform, dtype=np.float64)[:3, 3]
    return inverse


# --------------------------------------------------------------------------- field checks
def _read_json(path: Path):
    """The parsed JSON of the camera file ``path`` (a regular file of at most
    MAX_CAMERA_FILE_BYTES bytes, UTF-8)."""
    data = read_regular(path, MAX_CAMERA_FILE_BYTES, what="a camera file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(f"cannot read camera file: {err}", file=path) from None
    return load_json(text, file=path, what="the camera file")


def _check_intrinsics(width: int, height: int, values: tuple[float, float, float, float],
                      names: tuple[str, str, str, str], source, where: str) -> None:
    """InputError naming the file's field when (fx, fy, cx, cy) = ``values`` are not sane
    for the image (:func:`~csgs_codec.scene.camera.intrinsics_problem`); ``names`` are the
    file's names of the four."""
    problem = intrinsics_problem(width, height, *values)
    if problem is not None:
        field, message = problem
        name = names[("fx", "fy", "cx", "cy").index(field)]
        raise InputError(message, file=source, property=f"{where}.{name}")


def _field(entry: dict, key: str, source, where: str):
    if key not in entry:
        raise InputError("missing field", file=source, property=f"{where}.{key}")
    return entry[key]


def _finite(entry: dict, key: str, source, where: str) -> float:
    value = _field(entry, key, source, where)
    if isinstance(value, int) and not isinstance(value, bool):
        try:
            value = float(value)
        except OverflowError:  # JSON integers are unbounded
            raise InputError("number too large for a float", file=source,
                             property=f"{where}.{key}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"expected a finite number, got {value!r}", file=source,
                         property=f"{where}.{key}")
    return float(value)


def _positive(entry: dict, key: str, source, where: str) -> float:
    value = _finite(entry, key, source, where)
    if value <= 0:
        raise InputError(f"must be positive, got {value}", file=source, property=f"{where}.{key}")
    return value


def _image_side(entry: dict, key: str, source, where: str) -> int:
    value = _finite(entry, key, source, where)
    if value != int(value) or not 0 < value <= MAX_IMAGE_SIDE:
        raise InputError(f"expected a whole number of pixels in 1..{MAX_IMAGE_SIDE}, "
                         f"got {value}", file=source, property=f"{where}.{key}")
    return int(value)


def _nonzero_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value != 0


def _float_array(entry: dict, key: str, shape: tuple[int, ...], source, where: str,
                 allow_rows: int | None = None) -> np.ndarray:
    value = _field(entry, key, source, where)
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an integer past 1e308
        raise InputError(f"expected numbers of shape {shape}", file=source,
                         property=f"{where}.{key}") from None
    if allow_rows is not None and array.shape == (allow_rows, shape[1]):
        array = np.vstack([array, [0.0, 0.0, 0.0, 1.0]])
    if array.shape != shape:
        raise InputError(f"expected shape {shape}, got {array.shape}", file=source,
                         property=f"{where}.{key}")
    if not np.all(np.isfinite(array)):
        raise InputError("non-finite value", file=source, property=f"{where}.{key}")
    return array


def _check_rotation(rotation: np.ndarray, source, name: str) -> None:
    """Accept rotations up to a uniform scale error of 1e-3 (JSON round-off, float32 exports)."""
    gram = rotation.T @ rotation
    if not np.allclose(gram, np.eye(3), atol=1e-3) or np.linalg.det(rotation) <= 0:
        raise InputError("not a rotation (columns must be orthonormal, determinant +1)",
                         file=source, property=name)


def _size_from_image_file(folder: Path, file_path) -> dict[str, int]:
    """{"w", "h"} read from the frame's image (Blender-style files give no size); {} if the
    image cannot be read, so the missing field is reported."""
    if not isinstance(file_path, str) or not file_path:
        return {}
    if Path(file_path).is_absolute() or os.path.normpath(file_path).split(os.sep)[0] == "..":
        return {}  # outside the JSON's folder: not opened (the dataset loader's rule)
    image = folder / file_path
    candidates = [image] if image.suffix else [image.with_suffix(".png"), image]
    from PIL import Image

    for candidate in candidates:
        try:
            with open_regular(candidate) as file, Image.open(file) as handle:
                return {"w": handle.width, "h": handle.height}
        except (OSError, ValueError, InputError, Image.DecompressionBombError):
            continue
    return {}


def _transforms_focals(entry: dict, width: int, height: int, source, where: str
                       ) -> tuple[float, float]:
    """(fx, fy) from fl_x/fl_y or the field-of-view angles, whichever the file gives."""
    fx = _positive(entry, "fl_x", source, where) if "fl_x" in entry else None
    fy = _positive(entry, "fl_y", source, where) if "fl_y" in entry else None
    if fx is None and "camera_angle_x" in entry:
        fx = _focal_from_angle(entry, "camera_angle_x", width, source, where)
    if fy is None and "camera_angle_y" in entry:
        fy = _focal_from_angle(entry, "camera_angle_y", height, source, where)
    if fx is None and fy is None:
        raise InputError("missing field (or camera_angle_x)", file=source,
                         property=f"{where}.fl_x")
    return (fx if fx is not None else fy), (fy if fy is not None else fx)


def _focal_from_angle(entry: dict, key: str, side: int, source, where: str) -> float:
    angle = _finite(entry, key, source, where)
    if not 0 < angle < math.pi:
        raise InputError(f"field of view must be in (0, pi) radians, got {angle}",
                         file=source, property=f"{where}.{key}")
    return 0.5 * side / math.tan(0.5 * angle)
