"""Training datasets: images + cameras (+ instance masks) from the layouts trainers use.

Layouts :func:`load_dataset` recognises (``path`` is the dataset folder or its camera file):

* nerfstudio / instant-ngp ``transforms.json`` (or Blender's ``transforms_train.json``): each
  frame's ``file_path`` is relative to the JSON file's folder.
* INRIA ``cameras.json``: each ``img_name`` is looked up in the ``images/`` folder.
* COLMAP model (``sparse/0``, ``sparse`` or the folder itself): each image name is looked up
  in ``images/``.
* LLFF capture (``poses_bounds.npy``, :mod:`csgs_codec.scene.llff_io`): the images of
  ``images/``, or of the ``images_N/`` copy nearest above the asked size, in sorted name order.

The ``images/`` folder is searched beside the camera file, then one and two levels up (COLMAP
models sit in ``sparse/0``). Image names must stay inside the dataset folder: the folder
holding the camera file (transforms.json), the folder holding ``images/`` (INRIA, COLMAP), or
the ``images`` folder when one is given; an absolute name or one whose ``..`` climbs out is
refused unless ``allow_outside_paths`` (``--allow-outside-paths``) is set (docs/captures.md).

Masks: one integer instance-id image per view with the image's
stem (``masks/frame_001.png`` for ``images/frame_001.jpg``), from the ``masks/`` folder beside
the images unless another folder is given. A mask may also have the size of the full-size
image when an LLFF ``images_N/`` copy is read: it is then resized like the image. Without
masks, the built-in segmenter (:mod:`csgs_codec.train.segmentation`) makes them, with a
:class:`~csgs_codec.errors.FallbackWarning` (the CLI shows it even under ``--quiet``), and
marks them ``oversegmented`` (the semantic stages merge them into objects first).
Foreground masks (object vs background, :mod:`.foreground`) are named the same way; a
capture's ``masks/`` folder of 0/255 images is one (:func:`find_foreground_masks`), and is
then not read as instance masks.
"""

from __future__ import annotations

import contextlib
import numbers
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgs_codec.errors import FallbackWarning, InputError
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.cameras_io import load_cameras, resize_camera
from csgs_codec.scene.colmap_io import colmap_model_files, is_colmap_path
from csgs_codec.scene.llff_io import POSES_FILE, is_llff_path, load_llff_capture
from csgs_codec.train.foreground import (
    composite_foreground,
    is_binary_mask,
    read_foreground_mask,
)
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
                 read_masks: bool = True, foreground: str | Path | None = None,
                 allow_outside_paths: bool = False) -> list[TrainingView]:
    """Load every view of a dataset (layouts in the module notes).

    Args:
        path: dataset folder, or its ``transforms*.json`` / ``cameras.json`` / COLMAP model /
            LLFF ``poses_bounds.npy``.
        downscale: divide the image size by this factor (>= 1; sizes are rounded, intrinsics
            scaled to match); images are area-averaged, masks take the nearest id.
        masks: folder of instance-id images; default ``masks/`` beside the images when present
            (unless it is the ``foreground`` folder).
        images: folder of the images (default: found as described in the module notes);
            a transforms.json's ``file_path`` values are then relative to it instead of to
            the JSON file's folder (renders of the cameras made elsewhere, say).
        segment_missing: without a masks folder, make masks with the built-in segmenter
            (warning that quality depends on masks); False leaves ``mask`` None.
        background: RGB behind transparent image pixels, and behind the object where
            foreground masks are given.
        read_masks: False reads no masks at all (color-only training): ``mask`` stays None
            and ``masks`` / ``segment_missing`` are ignored.
        foreground: folder of foreground masks (:mod:`csgs_codec.train.foreground`; see
            :func:`find_foreground_masks` for a capture's own): each image is composited over
            ``background`` outside its mask (before any downscale) and the view's
            ``foreground`` set.
        allow_outside_paths: read image names that are absolute or climb out of the dataset
            folder with ``..`` (refused by default; module notes).

    Returns:
        One :class:`TrainingView` per camera, in the camera file's order (COLMAP: image name).

    Raises:
        InputError: no camera file, a missing or unreadable image or mask, an image whose size
            differs from its camera's, a mask whose size differs from its image's (each
            naming the file), or an image name leaving the dataset folder (naming the camera
            file, the frame or image, and the name).
    """
    if (isinstance(downscale, bool) or not isinstance(downscale, numbers.Real)
            or not 1.0 <= float(downscale) < float("inf")):
        raise InputError(f"downscale must be a finite factor >= 1, got {downscale}",
                         property="downscale")
    files = _view_files(Path(path), float(downscale), images, allow_outside_paths)
    foreground_root = None
    if foreground is not None:
        foreground_root = Path(foreground)
        if not foreground_root.is_dir():
            raise InputError("foreground masks folder not found", file=foreground_root)
    mask_root = _mask_folder(files.image_root, masks, foreground_root) if read_masks else None
    views = []
    for camera, name in zip(files.cameras, files.names):
        image_path = find_image(files.image_root, name)
        image = read_image(image_path, background, size=(camera.width, camera.height))
        if (image.shape[1], image.shape[0]) != (camera.width, camera.height):
            raise InputError(f"image is {image.shape[1]}x{image.shape[0]} but its camera is "
                             f"{camera.width}x{camera.height}", file=image_path)
        shape = image.shape[:2]
        mask = None if mask_root is None else _read_view_mask(mask_root, name, image_path,
                                                              shape, files.mask_scale)
        keep = None
        if foreground_root is not None:
            mask_path = _view_mask_path(foreground_root, name, "foreground mask")
            keep = fit_mask_to_image(read_foreground_mask(mask_path), mask_path, image_path,
                                     shape, files.mask_scale)
            image = composite_foreground(image, keep, background)
        camera, image, mask = _downscaled(camera, image, mask, files.downscale)
        if keep is not None:
            keep = resize_mask(keep, camera.width, camera.height)
        views.append(TrainingView(image, camera, mask, name=name, foreground=keep))
    if mask_root is None and segment_missing and read_masks:
        warnings.warn(_fallback_message(path, files.image_root, foreground_root),
                      FallbackWarning, stacklevel=2)
        for view in views:
            view.mask = segment_image(view.image)
            view.oversegmented = True
    return views


def _fallback_message(path, image_root: Path, foreground_root: Path | None) -> str:
    """What the built-in segmenter's warning says: where masks were looked for, how to give
    them, how to accept the fallback."""
    looked = " or ".join(f"'{folder.absolute()}'"
                         for folder in mask_folder_candidates(image_root))
    why = (f"no instance masks: none given and no folder {looked}" if foreground_root is None
           else f"no instance masks besides the foreground masks in '{foreground_root}'")
    return (f"{path}: {why}; making them with the built-in graph segmenter, which is much "
            "weaker than SAM-style masks. Give your masks with --masks DIR "
            "(docs/masks.md), or pass --builtin-segmenter to use the built-in one without "
            "this warning")


def find_foreground_masks(path: str | Path, *, images: str | Path | None = None,
                          allow_outside_paths: bool = False) -> Path | None:
    """The dataset's own foreground masks: its ``masks/`` folder (found as for instance
    masks) when every view has a mask there holding only 0 and 255 (see
    :func:`csgs_codec.train.foreground.is_binary_mask`), else None.

    Raises:
        InputError: as :func:`load_dataset` for the cameras and images.
    """
    files = _view_files(Path(path), 1.0, images, allow_outside_paths)
    folder = _mask_folder(files.image_root, None)
    if folder is None:
        return None
    for name in files.names:
        try:
            candidate = find_image(folder, Path(name).stem)
        except InputError:
            return None
        if not is_binary_mask(candidate):
            return None
    return folder


@dataclass(frozen=True)
class _ViewFiles:
    """Where a dataset's views are: cameras, their image folder and names, the downscale
    left to apply after reading, and a mask's size over its image's (LLFF's images_N/)."""

    cameras: list[Camera]
    image_root: Path
    names: list[str]
    downscale: float
    mask_scale: float


def _view_files(path: Path, downscale: float, images: str | Path | None,
                allow_outside_paths: bool = False) -> _ViewFiles:
    camera_path = find_camera_file(path)
    if is_llff_path(camera_path):
        capture = load_llff_capture(camera_path, downscale=downscale, folder=images)
        return _ViewFiles(capture.cameras, capture.folder, [c.name for c in capture.cameras],
                          capture.remaining_downscale, capture.scale)
    cameras = load_cameras(camera_path)
    image_root, names, dataset_root = _image_locations(camera_path, cameras, images)
    if not allow_outside_paths:
        check_names_inside(camera_path, names, image_root, dataset_root)
    return _ViewFiles(cameras, image_root, names, downscale, 1.0)


def find_camera_file(path: Path) -> Path:
    """The camera file or COLMAP model that ``path`` names or holds.

    Raises:
        InputError: ``path`` is missing or holds none of :data:`CAMERA_FILE_NAMES`, a
            COLMAP model or an LLFF ``poses_bounds.npy``.
    """
    if not path.exists():
        raise InputError("no such file or folder", file=path)
    if path.is_file() or is_colmap_path(path):
        return path
    for name in CAMERA_FILE_NAMES:
        if (path / name).is_file():
            return path / name
    if (path / POSES_FILE).is_file():
        return path / POSES_FILE
    raise InputError(f"no cameras found: expected one of {', '.join(CAMERA_FILE_NAMES)}, a "
                     f"COLMAP model (sparse/0) or an LLFF {POSES_FILE}", file=path)


def dataset_files(path: str | Path, *, masks: str | Path | None = None,
                  images: str | Path | None = None,
                  foreground: str | Path | None = None,
                  allow_outside_paths: bool = False) -> list[Path]:
    """The files :func:`load_dataset` (same arguments) would read: the camera file (or the
    COLMAP model's files), each view's image, and each instance or foreground mask it finds.
    Files that are missing are left out (loading reports them); no image is opened.

    Raises:
        InputError: as :func:`load_dataset` for a missing or malformed camera file.
    """
    camera_path = find_camera_file(Path(path))
    views = _view_files(Path(path), 1.0, images, allow_outside_paths)
    files = colmap_model_files(camera_path) if camera_path.is_dir() else [camera_path]
    foreground_root = None if foreground is None else Path(foreground)
    roots = [(views.image_root, False), (_mask_folder(views.image_root, masks, foreground_root),
                                         True), (foreground_root, True)]
    for name in views.names:
        for root, by_stem in roots:
            if root is not None:
                with contextlib.suppress(InputError, OSError, ValueError):
                    files.append(find_image(root, Path(name).stem if by_stem else name))
    return files


def _image_locations(camera_path: Path, cameras: list[Camera], images: str | Path | None
                     ) -> tuple[Path, list[str], Path]:
    """(folder the names are relative to, image name per camera, the dataset folder the
    names must stay inside)."""
    names = [camera.name for camera in cameras]
    if _is_transforms_file(camera_path) and images is None:
        return camera_path.parent, names, camera_path.parent
    if images is not None:
        folder = Path(images)
        if not folder.is_dir():
            raise InputError("images folder not found", file=folder)
        return folder, names, folder
    start = camera_path if camera_path.is_dir() else camera_path.parent
    for folder in (start, start.parent, start.parent.parent):
        if (folder / IMAGES_FOLDER).is_dir():
            return folder / IMAGES_FOLDER, names, folder
    raise InputError(f"no '{IMAGES_FOLDER}' folder beside the cameras or up to two levels "
                     "above", file=start / IMAGES_FOLDER)


def check_names_inside(camera_path: Path, names: list[str], image_root: Path,
                       dataset_root: Path) -> None:
    """Refuse an image name that is absolute or whose ``..`` leaves ``dataset_root`` once
    joined to ``image_root`` (a folder inside it). The test is on the names as written,
    not on resolved paths, so a dataset whose ``images/`` is a symlink still loads.

    Raises:
        InputError: naming the camera file, the frame or image (``property``) and the path.
    """
    prefix = os.path.relpath(os.path.abspath(image_root), os.path.abspath(dataset_root))
    for index, name in enumerate(names):
        joined = os.path.normpath(os.path.join(prefix, name))
        if Path(name).is_absolute() or joined == os.pardir or joined.startswith(
                os.pardir + os.sep):
            raise InputError(f"image path {name!r} is outside the dataset folder "
                             f"'{dataset_root}'; pass --allow-outside-paths to read it",
                             file=_names_file(camera_path),
                             property=_name_field(camera_path, index, name))


def _names_file(camera_path: Path) -> Path:
    """The file holding the image names: the camera file, or a COLMAP model's images file."""
    if camera_path.is_dir():
        return next((f for f in colmap_model_files(camera_path) if f.stem == "images"),
                    camera_path)
    return camera_path


def _name_field(camera_path: Path, index: int, name: str) -> str:
    """Where the camera file gives view ``index``'s image name."""
    if camera_path.is_dir() or camera_path.suffix.lower() in (".txt", ".bin"):
        return f"image {name[:80]}"  # COLMAP: views are sorted by name
    if _is_transforms_file(camera_path):
        return f"frames[{index}].file_path"
    return f"[{index}].img_name"


def _is_transforms_file(camera_path: Path) -> bool:
    """True for a transforms.json-style file (a JSON object; INRIA files hold a list)."""
    if not camera_path.is_file() or camera_path.suffix.lower() != ".json":
        return False
    with open_regular(camera_path) as handle:
        head = handle.read(4096).lstrip()
    return head.startswith(b"{") or head.startswith(b"\xef\xbb\xbf{")


def _mask_folder(image_root: Path, masks: str | Path | None,
                 foreground: Path | None = None) -> Path | None:
    """The instance-mask folder: ``masks`` when given, else ``masks/`` beside the images
    unless that folder holds the foreground masks."""
    if masks is not None:
        folder = Path(masks)
        if not folder.is_dir():
            raise InputError("masks folder not found", file=folder)
        return folder
    for folder in mask_folder_candidates(image_root):
        if folder.is_dir():
            if foreground is not None and folder.resolve() == foreground.resolve():
                return None
            return folder
    return None


def mask_folder_candidates(image_root: Path) -> tuple[Path, Path]:
    """The folders looked in, in order, for instance masks that are not given: ``masks/``
    in the image folder, then beside it."""
    return image_root / MASKS_FOLDER, image_root.parent / MASKS_FOLDER


def _view_mask_path(mask_root: Path, image_name: str, what: str = "mask") -> Path:
    """The mask file of ``image_name`` in ``mask_root`` (its stem, any image suffix)."""
    stem = Path(image_name).stem
    try:
        return find_image(mask_root, stem)
    except InputError:
        raise InputError(f"no {what} for image '{image_name}'",
                         file=mask_root / f"{stem}.png") from None


def _read_view_mask(mask_root: Path, image_name: str, image_path: Path,
                    shape: tuple[int, int], scale: float = 1.0) -> np.ndarray:
    """The (H, W) = ``shape`` instance mask of an image; a mask ``scale`` times the image's
    size (one of a full-size LLFF image read from ``images_N/``) is resized to it."""
    mask_path = _view_mask_path(mask_root, image_name)
    # Sizes are checked before decoding, except a full-size LLFF mask's (resized below).
    mask = read_mask(mask_path, size=(shape[1], shape[0]) if scale == 1.0 else None,
                     owner=f"its image {image_path}")
    ids = len(np.unique(mask))
    if ids > MAX_MASKS_PER_VIEW:
        raise InputError(f"mask holds {ids:,} ids, more than the {MAX_MASKS_PER_VIEW:,} a "
                         "view may hold (every pair of a view's masks is compared)",
                         file=mask_path)
    return fit_mask_to_image(mask, mask_path, image_path, shape, scale)


def fit_mask_to_image(mask: np.ndarray, mask_path: Path, image_path: Path,
                      shape: tuple[int, int], scale: float = 1.0) -> np.ndarray:
    """``mask`` (h, w) as (H, W) = ``shape``: unchanged when sizes agree, resized by nearest
    neighbour when it is ``scale`` times the image's size (within a pixel, LLFF's rounding).

    Raises:
        InputError: naming both files and sizes when they do not agree.
    """
    if mask.shape == shape:
        return mask
    height, width = shape
    if scale != 1.0 and all(abs(m - s * scale) <= 1.0 for m, s in zip(mask.shape, shape)):
        return resize_mask(mask, width, height)
    raise InputError(f"mask is {mask.shape[1]}x{mask.shape[0]} but its image {image_path} is "
                     f"{width}x{height}", file=mask_path)


def _downscaled(camera: Camera, image: np.ndarray, mask: np.ndarray | None, factor: float
                ) -> tuple[Camera, np.ndarray, np.ndarray | None]:
    if factor == 1.0:
        return camera, image, mask
    width = max(1, round(camera.width / factor))
    height = max(1, round(camera.height / factor))
    return (resize_camera(camera, width, height), resize_image(image, width, height),
            None if mask is None else resize_mask(mask, width, height))
