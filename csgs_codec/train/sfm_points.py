"""Structure-from-motion points of a capture whose camera poses are known, by pycolmap.

Stage 1 grows anchors from an initial point cloud; real captures that come with poses but no
points (a transforms.json without ``ply_file_path``, a COLMAP model without points3D) get
them here rather than from random points: SIFT features of the views' images, exhaustive
matching, and triangulation with the cameras held at the dataset's intrinsics and poses
(COLMAP's point triangulator; nothing is re-estimated). pycolmap comes with the ``train``
extra.

The views' images are written as 8-bit PNGs (the pixels training sees, after any downscale)
into a cache folder named by a hash of the images and cameras, with the triangulated points
(``points.npy``) beside them, so a second run on the same views reads the points back.
The cache root is ``$CSGS_CACHE`` or ``~/.cache/csgs``, under ``sfm/``.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgs_codec.errors import CsgsWarning, InputError, UnsupportedError
from csgs_codec.train.views import TrainingView
from csgs_codec.untrusted import read_npy

#: Fewer triangulated points than this are not worth starting from (random points then).
MIN_POINTS = 32
#: Environment variable that moves the cache root.
CACHE_ENV = "CSGS_CACHE"
#: Largest cached points file read (10^8 float64 points).
MAX_CACHE_BYTES = 24 * 10**8


@dataclass(frozen=True)
class SfmPoints:
    """Triangulated points.

    Attributes:
        points: (P, 3) float64 world positions.
        cached: True when they were read from the cache rather than triangulated now.
        folder: the cache folder (images, database, points.npy).
    """

    points: np.ndarray
    cached: bool
    folder: Path


def pycolmap_available() -> bool:
    """True when pycolmap imports."""
    try:
        import pycolmap  # noqa: F401
    except ImportError:
        return False
    return True


def cache_root() -> Path:
    """Where triangulations are cached: ``$CSGS_CACHE/sfm`` or ``~/.cache/csgs/sfm``."""
    base = os.environ.get(CACHE_ENV)
    return (Path(base) if base else Path.home() / ".cache" / "csgs") / "sfm"


def views_key(views: list[TrainingView]) -> str:
    """Hex digest of the views' 8-bit pixels and cameras (intrinsics, size, pose)."""
    digest = hashlib.sha256()
    for view in views:
        c = view.camera
        digest.update(np.asarray([c.width, c.height, c.fx, c.fy, c.cx, c.cy],
                                 np.float64).tobytes())
        digest.update(np.asarray(c.world_to_camera, np.float64).tobytes())
        digest.update(_pixels(view).tobytes())
    return digest.hexdigest()[:24]


def triangulate_views(views: list[TrainingView], *, cache: Path | None = None
                      ) -> SfmPoints:
    """Points triangulated from the views' images at their known cameras (module notes).

    Args:
        views: at least two views with images and cameras.
        cache: the cache root (default :func:`cache_root`).

    Raises:
        InputError: fewer than two views.
        UnsupportedError: pycolmap is not installed.
    """
    if len(views) < 2:
        raise InputError("triangulating points needs at least two views", property="views")
    if not pycolmap_available():
        raise UnsupportedError("triangulating initial points needs pycolmap: pip install "
                               "'csgs[train]'")
    folder = (cache or cache_root()) / views_key(views)
    stored = folder / "points.npy"
    points = cached_points(stored)
    if points is not None:
        return SfmPoints(points, True, folder)
    points = _triangulate(views, folder)
    temporary = folder / "points.tmp.npy"
    np.save(temporary, points)
    os.replace(temporary, stored)
    return SfmPoints(points, False, folder)


def cached_points(stored: Path) -> np.ndarray | None:
    """The (P, 3) float64 points cached in ``stored``, or None when there are none. A damaged
    cache file (truncated by a crash, say) is warned about and ignored, so the caller
    triangulates again and replaces it, instead of every later run failing on it."""
    if not stored.is_file():
        return None
    try:
        points = read_npy(stored, MAX_CACHE_BYTES, what="cached SfM points", kinds="f")
    except InputError as err:
        reason = err.message
    else:
        if points.ndim == 2 and points.shape[1] == 3 and np.isfinite(points).all():
            return points.astype(np.float64)
        reason = f"holds {points.shape} values, not finite (P, 3) points"
    warnings.warn(f"{stored}: damaged triangulation cache ({reason}); triangulating again",
                  CsgsWarning, stacklevel=3)
    return None


def _pixels(view: TrainingView) -> np.ndarray:
    return np.clip(np.rint(view.image * 255.0), 0, 255).astype(np.uint8)


def _triangulate(views: list[TrainingView], folder: Path) -> np.ndarray:
    """Extract, match and triangulate in ``folder`` (made afresh): (P, 3) float64."""
    import pycolmap
    from PIL import Image

    # COLMAP logs every image and match at INFO; the caller reports the outcome instead.
    pycolmap.logging.minloglevel = max(int(pycolmap.logging.minloglevel), 2)
    if folder.exists():
        shutil.rmtree(folder)
    images = folder / "images"
    images.mkdir(parents=True)
    names = []
    for i, view in enumerate(views):
        name = f"view_{i:05d}.png"
        Image.fromarray(_pixels(view)).save(images / name)
        names.append(name)
    database = folder / "database.db"
    cpu = pycolmap.Device.cpu
    pycolmap.extract_features(database, images, image_names=names,
                              camera_mode=pycolmap.CameraMode.PER_IMAGE, device=cpu)
    pycolmap.match_exhaustive(database, device=cpu)
    camera_of = dict(zip(names, (view.camera for view in views)))
    reconstruction = pycolmap.Reconstruction()
    db = pycolmap.Database.open(database)
    try:
        for record in db.read_all_images():
            camera = camera_of[record.name]
            known = pycolmap.Camera(model="PINHOLE", width=camera.width, height=camera.height,
                                    params=[camera.fx, camera.fy, camera.cx, camera.cy],
                                    camera_id=record.camera_id)
            db.update_camera(known)
            reconstruction.add_camera_with_trivial_rig(known)
            pose = np.asarray(camera.world_to_camera, np.float64)
            image = pycolmap.Image(name=record.name, camera_id=record.camera_id,
                                   image_id=record.image_id)
            reconstruction.add_image_with_trivial_frame(
                image, pycolmap.Rigid3d(pycolmap.Rotation3d(pose[:3, :3]), pose[:3, 3]))
    finally:
        db.close()
    result = pycolmap.triangulate_points(reconstruction, database, images, folder / "model")
    points = np.array([p.xyz for p in result.points3D.values()], np.float64).reshape(-1, 3)
    return points[np.isfinite(points).all(axis=1)]
