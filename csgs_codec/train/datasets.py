"""Training datasets: images + cameras (+ instance masks) from the layouts trainers use.

Layouts :func:`load_dataset` recognises (``path`` is the dataset folder or its camera file):

* nerfstudio / instant-ngp ``transforms.json`` (or Blender's ``transforms_train.json``): each
  frame's ``file_path`` is relative to the JSON file's folder.
* INRIA ``cameras.json``: each ``img_name`` is looked up in the ``images/`` folder.
* COLMAP model (``sparse/0``, ``sparse`` or the folder itself): each image name is looked up
  in ``images/``.

The ``images/`` folder is searched beside the camera file, then one and two levels up (COLMAP
models sit in ``sparse/0``). Masks: one integer instance-id image per view with the image's
stem (``masks/frame_001.png`` for ``images/frame_001.jpg``), from the ``masks/`` folder beside
the images unless another folder is given. Without masks, the built-in segmenter
(:mod:`csgs_codec.train.segmentation`) makes them, with a :class:`CsgsWarning`.
"""

from __future__ import annotations

import contextlib
import numbers
import warnings
from pathlib import Path

import numpy as np

from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.cameras_io import load_cameras, resize_camera
from csgs_codec.scene.colmap_io import colmap_model_files, is_colmap_path
from csgs_codec.train.image_files import (
    find_image,
    read_image,
    read_mask,
    resize_image,
    resize_mask,
)
from csgs_codec.train.segmentation import segment_image
from csgs_codec.train.semantic_batch import MAX_MASKS_PER_VIEW
from csgs_codec.train.views import TrainingView
from csgs_codec.untrusted import open_regular

#: Camera files looked for, in order, in a dataset folder.
CAMERA_FILE_NAMES = ("transforms.json", "transforms_train.json", "cameras.json")
#: Name of the mask folder looked for beside the images.
MASKS_FOLDER = "masks"
#: Name of the image folder of INRIA and COLMAP datasets.
IMAGES_FOLDER = "images"


def load_dataset(path: str | Path, *, downscale: float = 1.0, masks: str | Path | None = None,
                 images: str | Path | None = None, segment_missing: bool = True,
                 background: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 read_masks: bool = True) -> list[TrainingView]:
    """Load every view of a dataset (layouts in the module notes).

    Args:
        path: dataset folder, or its ``transforms*.json`` / ``cameras.json`` / COLMAP model.
        downscale: divide the image size by this factor (>= 1; sizes are rounded, intrinsics
            scaled to match); images are area-averaged, masks take the nearest id.
        masks: folder of instance-id images; default ``masks/`` beside the images when present.
        images: folder of the images for INRIA and COLMAP layouts (default: found as described
            in the module notes); ignored for transforms.json, whose paths are explicit.
        segment_missing: without a masks folder, make masks with the built-in segmenter
            (warning that quality depends on masks); False leaves ``mask`` None.
        background: RGB behind transparent image pixels.
        read_masks: False reads no masks at all (color-only training): ``mask`` stays None
            and ``masks`` / ``segment_missing`` are ignored.

    Returns:
        One :class:`TrainingView` per camera, in the camera file's order (COLMAP: image name).

    Raises:
        InputError: no camera file, a missing or unreadable image or mask, an image whose size
            differs from its camera's, or a mask whose size differs from its image's (each
            naming the file).
    """
    if (isinstance(downscale, bool) or not isinstance(downscale, numbers.Real)
            or not 1.0 <= float(downscale) < float("inf")):
        raise InputError(f"downscale must be a finite factor >= 1, got {downscale}",
                         property="downscale")
    camera_path = find_camera_file(Path(path))
    cameras = load_cameras(camera_path)
    image_root, image_names = _image_locations(camera_path, cameras, images)
    mask_root = _mask_folder(image_root, masks) if read_masks else None
    views = []
    for camera, name in zip(cameras, image_names):
        image_path = find_image(image_root, name)
        image = read_image(image_path, background, size=(camera.width, camera.height))
        if (image.shape[1], image.shape[0]) != (camera.width, camera.height):
            raise InputError(f"image is {image.shape[1]}x{image.shape[0]} but its camera is "
                             f"{camera.width}x{camera.height}", file=image_path)
        mask = None if mask_root is None else _read_view_mask(mask_root, name, image.shape[:2])
        camera, image, mask = _downscaled(camera, image, mask, float(downscale))
        views.append(TrainingView(image, camera, mask, name=name))
    if mask_root is None and segment_missing and read_masks:
        warnings.warn(f"{path}: no masks folder; making instance masks with the built-in "
                      "graph segmenter. Semantic quality depends on the masks: give SAM-style "
                      "masks in a masks/ folder for good results", CsgsWarning, stacklevel=2)
        for view in views:
            view.mask = segment_image(view.image)
    return views


def find_camera_file(path: Path) -> Path:
    """The camera file or COLMAP model that ``path`` names or holds.

    Raises:
        InputError: ``path`` is missing or holds none of :data:`CAMERA_FILE_NAMES` nor a
            COLMAP model.
    """
    if not path.exists():
        raise InputError("no such file or folder", file=path)
    if path.is_file() or is_colmap_path(path):
        return path
    for name in CAMERA_FILE_NAMES:
        if (path / name).is_file():
            return path / name
    raise InputError(f"no cameras found: expected one of {', '.join(CAMERA_FILE_NAMES)} or a "
                     "COLMAP model (sparse/0)", file=path)


def dataset_files(path: str | Path, *, masks: str | Path | None = None,
                  images: str | Path | None = None) -> list[Path]:
    """The files :func:`load_dataset` (same arguments) would read: the camera file (or the
    COLMAP model's files), each view's image and each mask it finds. Files that are missing
    are left out (loading reports them); no image is opened.

    Raises:
        InputError: as :func:`load_dataset` for a missing or malformed camera file.
    """
    camera_path = find_camera_file(Path(path))
    cameras = load_cameras(camera_path)
    files = colmap_model_files(camera_path) if camera_path.is_dir() else [camera_path]
    image_root, names = _image_locations(camera_path, cameras, images)
    mask_root = _mask_folder(image_root, masks)
    for name in names:
        for root, stem in ((image_root, name), (mask_root, Path(name).stem)):
            if root is not None:
                with contextlib.suppress(InputError, OSError, ValueError):
                    files.append(find_image(root, stem))
    return files


def _image_locations(camera_path: Path, cameras: list[Camera], images: str | Path | None
                     ) -> tuple[Path, list[str]]:
    """(folder the names are relative to, image name per camera)."""
    names = [camera.name for camera in cameras]
    if _is_transforms_file(camera_path):
        return camera_path.parent, names
    if images is not None:
        folder = Path(images)
        if not folder.is_dir():
            raise InputError("images folder not found", file=folder)
        return folder, names
    start = camera_path if camera_path.is_dir() else camera_path.parent
    for folder in (start, start.parent, start.parent.parent):
        if (folder / IMAGES_FOLDER).is_dir():
            return folder / IMAGES_FOLDER, names
    raise InputError(f"no '{IMAGES_FOLDER}' folder beside the cameras or up to two levels "
                     "above", file=start / IMAGES_FOLDER)


def _is_transforms_file(camera_path: Path) -> bool:
    """True for a transforms.json-style file (a JSON object; INRIA files hold a list)."""
    if not camera_path.is_file() or camera_path.suffix.lower() != ".json":
        return False
    with open_regular(camera_path) as handle:
        head = handle.read(4096).lstrip()
    return head.startswith(b"{") or head.startswith(b"\xef\xbb\xbf{")


def _mask_folder(image_root: Path, masks: str | Path | None) -> Path | None:
    if masks is not None:
        folder = Path(masks)
        if not folder.is_dir():
            raise InputError("masks folder not found", file=folder)
        return folder
    for folder in (image_root / MASKS_FOLDER, image_root.parent / MASKS_FOLDER):
        if folder.is_dir():
            return folder
    return None


def _read_view_mask(mask_root: Path, image_name: str, shape: tuple[int, int]) -> np.ndarray:
    stem = Path(image_name).stem
    try:
        mask_path = find_image(mask_root, stem)
    except InputError:
        raise InputError(f"no mask for image '{image_name}'",
                         file=mask_root / f"{stem}.png") from None
    mask = read_mask(mask_path, size=(shape[1], shape[0]))
    ids = len(np.unique(mask))
    if ids > MAX_MASKS_PER_VIEW:
        raise InputError(f"mask holds {ids:,} ids, more than the {MAX_MASKS_PER_VIEW:,} a "
                         "view may hold (every pair of a view's masks is compared)",
                         file=mask_path)
    if mask.shape != shape:
        raise InputError(f"mask is {mask.shape[1]}x{mask.shape[0]} but its image is "
                         f"{shape[1]}x{shape[0]}", file=mask_path)
    return mask


def _downscaled(camera: Camera, image: np.ndarray, mask: np.ndarray | None, factor: float
                ) -> tuple[Camera, np.ndarray, np.ndarray | None]:
    if factor == 1.0:
        return camera, image, mask
    width = max(1, round(camera.width / factor))
    height = max(1, round(camera.height / factor))
    return (resize_camera(camera, width, height), resize_image(image, width, height),
            None if mask is None else resize_mask(mask, width, height))
