"""LLFF captures: ``poses_bounds.npy`` with ``images/`` (and ``images_N/`` copies) -> cameras.

``poses_bounds.npy`` is an (N, 17) array, one row per image in sorted file-name order (as
LLFF's loader sorts them): a 3x5 matrix ``[R | t | hwf]`` flattened row by row, then the near
and far depth bounds of the view. ``R``'s columns are the camera's down, right and backward
axes in world coordinates (camera-to-world), ``t`` the camera centre, and ``hwf`` the height,
width and focal length in pixels of the full-size images. The principal point is the image
centre (LLFF assumes it). In OpenCV axes (x right, y down, z forward) the camera-to-world
columns are therefore ``(R[:, 1], R[:, 0], -R[:, 2])``.

Image folders: ``images/`` holds the full-size images, ``images_N/`` LLFF's copies at 1/N of
the size (``images_4/``, ``images_8/``). Which one is read depends on the downscale asked for
(:func:`load_llff_capture`), and every view's intrinsics are scaled to the size of its image
in that folder, measured from the file, not inferred from N.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.camera import (
    MAX_CAMERA_FILE_BYTES,
    MAX_IMAGE_SIDE,
    Camera,
    intrinsics_problem,
)
from csgs_codec.untrusted import open_regular, read_npy, read_regular

#: The pose file of an LLFF capture.
POSES_FILE = "poses_bounds.npy"
#: Image file name endings LLFF reads (compared case-insensitively).
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")
#: Names of the 17 columns of a poses_bounds.npy row, for error messages.
COLUMN_NAMES = tuple([f"R[{r}][{c}]" if c < 3 else f"t[{r}]" if c == 3 else
                      ("height", "width", "focal")[r] for r in range(3) for c in range(5)]
                     + ["near", "far"])
_FOLDER_NAME = re.compile(r"images(?:_(\d+))?")


@dataclass(frozen=True)
class LlffPoses:
    """The parsed rows of a poses_bounds.npy.

    Attributes:
        camera_to_world: (N, 4, 4) float64, OpenCV axes (x right, y down, z forward).
        hwf: (N, 3) float64 full-size image height, width (pixels) and focal length (pixels).
        bounds: (N, 2) float64 near and far scene depth bounds (world units).
    """

    camera_to_world: np.ndarray
    hwf: np.ndarray
    bounds: np.ndarray


@dataclass(frozen=True)
class LlffCapture:
    """The cameras of an LLFF capture as read from one image folder.

    Attributes:
        cameras: one per image, in sorted file-name order, named by the image's file name.
        folder: the image folder read (``images/`` or ``images_N/``).
        scale: the default folder's image width over this folder's (1 for the default).
        remaining_downscale: what is left of the asked downscale after the folder's own
            (>= 1; 1 when the folder already has the asked size).
    """

    cameras: list[Camera]
    folder: Path
    scale: float
    remaining_downscale: float


def is_llff_path(path: str | Path) -> bool:
    """True when ``path`` is a ``poses_bounds.npy`` file or a folder holding one."""
    path = Path(path)
    if path.name == POSES_FILE and path.is_file():
        return True
    return path.is_dir() and (path / POSES_FILE).is_file()


def poses_file(path: str | Path) -> Path:
    """The ``poses_bounds.npy`` that ``path`` names or holds."""
    path = Path(path)
    return path / POSES_FILE if path.is_dir() else path


def read_poses_bounds(path: str | Path) -> LlffPoses:
    """Parse and check a ``poses_bounds.npy`` (module notes).

    Raises:
        InputError: naming the file, and the row (in the message) and column (``property``)
            where one is at fault: not a NumPy array, a shape other than (N, 17), a non-finite
            value, a size that is not a whole number of pixels, a focal length <= 0, or a
            rotation that is not one.
    """
    path = Path(path)
    data = read_regular(path, MAX_CAMERA_FILE_BYTES, what="a camera file")
    if not data.startswith(b"\x93NUMPY"):
        raise InputError("not a NumPy .npy file (it lacks the \\x93NUMPY magic)", file=path)
    # read_npy checks the header against the file before any array is made (numpy's own
    # parser raised tokenize and overflow errors on hostile headers).
    array = read_npy(path, MAX_CAMERA_FILE_BYTES, what="a camera file", kinds="biuf")
    if not isinstance(array, np.ndarray) or array.dtype.kind not in "fiu":
        raise InputError(f"expected a float array, got {getattr(array, 'dtype', type(array))}",
                         file=path)
    if array.ndim != 2 or array.shape[1] != len(COLUMN_NAMES) or array.shape[0] == 0:
        raise InputError(f"expected shape (N, {len(COLUMN_NAMES)}) with N >= 1 (a 3x5 pose "
                         f"and near/far per image), got {array.shape}", file=path)
    array = array.astype(np.float64)
    bad = np.argwhere(~np.isfinite(array))
    if len(bad):
        row, column = (int(v) for v in bad[0])
        raise InputError(f"row {row}: non-finite value {array[row, column]}", file=path,
                         property=COLUMN_NAMES[column])
    matrices = array[:, :15].reshape(-1, 3, 5)
    hwf = matrices[:, :, 4].copy()
    for row in range(len(array)):
        _check_row(matrices[row], hwf[row], path, row)
    rotation = matrices[:, :, :3]
    camera_to_world = np.tile(np.eye(4), (len(array), 1, 1))
    camera_to_world[:, :3, 0] = rotation[:, :, 1]   # right
    camera_to_world[:, :3, 1] = rotation[:, :, 0]   # down
    camera_to_world[:, :3, 2] = -rotation[:, :, 2]  # forward
    camera_to_world[:, :3, 3] = matrices[:, :, 3]
    return LlffPoses(camera_to_world, hwf, array[:, 15:17].copy())


def _check_row(matrix: np.ndarray, hwf: np.ndarray, path: Path, row: int) -> None:
    for name, value in zip(("height", "width"), hwf[:2]):
        if value != int(value) or not 0 < value <= MAX_IMAGE_SIDE:
            raise InputError(f"row {row}: expected a whole number of pixels in "
                             f"1..{MAX_IMAGE_SIDE}, got {value}", file=path, property=name)
    if hwf[2] <= 0:
        raise InputError(f"row {row}: focal length must be positive, got {hwf[2]}", file=path,
                         property="focal")
    rotation = matrix[:, :3]
    # LLFF's (down, right, back) columns are a right-handed frame too: det +1.
    if (not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-3)
            or np.linalg.det(rotation) <= 0):
        raise InputError(f"row {row}: R is not a rotation (columns must be orthonormal, "
                         "determinant +1)",
                         file=path, property="R")


def image_folders(root: Path) -> list[Path]:
    """The ``images/`` and ``images_N/`` folders under ``root``, ``images/`` first, then by N."""
    found = []
    for child in root.iterdir() if root.is_dir() else ():
        match = _FOLDER_NAME.fullmatch(child.name)
        if match and child.is_dir():
            found.append((int(match.group(1) or 1), child.name, child))
    return [folder for _, _, folder in sorted(found)]


def image_names(folder: Path) -> list[str]:
    """File names of the images in ``folder``, sorted as LLFF sorts them."""
    return sorted(p.name for p in folder.iterdir()
                  if p.suffix.lower() in IMAGE_EXTENSIONS and p.is_file())


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) of an image file, from its header.

    Raises:
        InputError: naming the file when it cannot be read.
    """
    from PIL import Image

    try:
        with open_regular(path) as file, Image.open(file) as handle:
            return int(handle.width), int(handle.height)
    except (OSError, ValueError, Image.DecompressionBombError) as error:
        raise InputError(f"cannot read image: {error}", file=path) from None


def load_llff_capture(path: str | Path, *, downscale: float = 1.0,
                      folder: str | Path | None = None) -> LlffCapture:
    """The cameras of the LLFF capture ``path`` (its folder or its ``poses_bounds.npy``).

    Args:
        downscale: the factor (>= 1) the caller will divide the default folder's image size
            by. The folder read is the one whose images are the smallest that are still at
            least that large, so little is resized and nothing is enlarged. The default folder
            is ``images/``, else the ``images_N/`` with the smallest N.
        folder: read this image folder instead of choosing one.

    Raises:
        InputError: a bad poses file (see :func:`read_poses_bounds`), no image folder, a
            number of images other than the number of rows (naming both), or an image whose
            aspect ratio differs from its row's (naming the image).
    """
    source = poses_file(path)
    poses = read_poses_bounds(source)
    root = source.parent
    if folder is not None:
        chosen = Path(folder)
        if not chosen.is_dir():
            raise InputError("images folder not found", file=chosen)
        return _capture(poses, source, chosen, 1.0, float(downscale))
    folders = image_folders(root)
    if not folders:
        raise InputError(f"no images/ (or images_N/) folder beside {POSES_FILE}",
                         file=root / "images")
    widths = {}
    for candidate in folders:
        names = image_names(candidate)
        if names:
            widths[candidate] = image_size(candidate / names[0])[0]
    if not widths:
        raise InputError(f"no .png/.jpg images in {folders[0].name}/ beside {POSES_FILE}",
                         file=folders[0])
    default = next(iter(widths))
    chosen, scale = default, 1.0
    for candidate, width in widths.items():
        factor = widths[default] / width
        if scale < factor <= downscale * (1 + 1e-9):
            chosen, scale = candidate, factor
    return _capture(poses, source, chosen, scale, max(1.0, downscale / scale))


def _capture(poses: LlffPoses, source: Path, folder: Path, scale: float,
             remaining: float) -> LlffCapture:
    names = image_names(folder)
    rows = len(poses.hwf)
    if len(names) != rows:
        raise InputError(f"{source.name} has {rows} rows but {folder} holds {len(names)} "
                         "images (.png/.jpg): one image per row is expected", file=source)
    cameras = []
    for row, name in enumerate(names):
        width, height = image_size(folder / name)
        full_height, full_width, focal = poses.hwf[row]
        if abs(width * full_height - height * full_width) > max(full_width, full_height):
            raise InputError(f"image is {width}x{height} but row {row} of {source.name} is "
                             f"{full_width:g}x{full_height:g}: a different aspect ratio",
                             file=folder / name)
        sx, sy = width / full_width, height / full_height
        problem = intrinsics_problem(width, height, focal * sx, focal * sy, width / 2,
                                     height / 2)
        if problem is not None:
            raise InputError(f"row {row}: {problem[1]}", file=source, property="focal")
        camera_to_world = poses.camera_to_world[row]
        world_to_camera = np.eye(4)
        world_to_camera[:3, :3] = camera_to_world[:3, :3].T
        world_to_camera[:3, 3] = -camera_to_world[:3, :3].T @ camera_to_world[:3, 3]
        cameras.append(Camera(width, height, focal * sx, focal * sy, width / 2, height / 2,
                              world_to_camera, name=name))
    return LlffCapture(cameras, folder, scale, remaining)
