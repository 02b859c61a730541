"""Points that stage 1 grows its anchors from: a point cloud given with the dataset, or random.

Looked for in this order (:func:`find_initial_points`):

1. a PLY named by the caller (any PLY with ``x``, ``y``, ``z`` vertex properties: a 3DGS
   scene, a COLMAP ``points3D.ply`` export, a scan);
2. the ``ply_file_path`` entry of a nerfstudio ``transforms.json``;
3. ``scene.ply`` beside the camera file (what :meth:`SyntheticDataset.write` adds);
4. a COLMAP ``points3D.bin`` or ``points3D.txt`` in the model folder;
5. points triangulated from the training views' images at their known poses with pycolmap
   (:mod:`csgs_codec.train.sfm_points`; cached), when views are given, pycolmap is installed
   and at least :data:`~csgs_codec.train.sfm_points.MIN_POINTS` come out;
6. otherwise uniform random points in the ball the cameras look into (Scaffold-GS's fallback
   for scenes without structure-from-motion points), from a seed, with a warning.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.scene.camera import MAX_CAMERA_FILE_BYTES, Camera
from csgs_codec.train.datasets import find_camera_file
from csgs_codec.untrusted import load_json, read_regular

#: File name of the ground-truth scene a synthetic dataset carries.
SCENE_FILE = "scene.ply"
#: Random points used when a dataset has no point cloud.
RANDOM_POINT_COUNT = 10_000
#: Binary COLMAP points3D records this many fixed bytes before each track.
_POINT_RECORD = struct.Struct("<Q3d3BdQ")


def read_ply_points(path: str | Path) -> np.ndarray:
    """(N, 3) float64 vertex positions of any PLY with x, y, z properties.

    Raises:
        InputError: unreadable file, no vertex element, or x/y/z missing or not finite.
    """
    from csgs_codec.interchange.ply_reader import read_vertex_columns

    path = Path(path)
    data = read_regular(path, what="a point file")
    _, _, columns = read_vertex_columns(data, source=str(path))
    for axis in "xyz":
        if axis not in columns:
            raise InputError("vertex has no position property", file=path, property=axis)
    points = np.stack([np.asarray(columns[a], np.float64) for a in "xyz"], axis=1)
    _check_finite(points, path)
    return points


def _check_finite(points: np.ndarray, path: Path) -> None:
    if len(points) == 0:
        raise InputError("holds no points", file=path, property="points")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise InputError("non-finite point", file=path, index=int(np.flatnonzero(bad)[0]))


def read_colmap_points(model: str | Path) -> np.ndarray:
    """(N, 3) float64 positions from a COLMAP model's ``points3D.bin`` or ``points3D.txt``.

    Raises:
        InputError: no points file in ``model``; a malformed file (naming the
            byte offset or line).
    """
    model = Path(model)
    binary, text = model / "points3D.bin", model / "points3D.txt"
    if binary.is_file():
        return _colmap_points_bin(binary)
    if text.is_file():
        return _colmap_points_txt(text)
    raise InputError("no points3D.bin or points3D.txt", file=model)


def _colmap_points_bin(path: Path) -> np.ndarray:
    data = read_regular(path, what="points3D.bin")
    if len(data) < 8:
        raise InputError("file shorter than its point count", file=path, offset=0)
    (count,) = struct.unpack_from("<Q", data, 0)
    if count > (len(data) - 8) // _POINT_RECORD.size:
        raise InputError(f"declares {count} points, more than its {len(data)} bytes hold",
                          file=path, offset=0)
    points = np.empty((count, 3), np.float64)
    offset = 8
    for i in range(count):
        if offset + _POINT_RECORD.size > len(data):
            raise InputError(f"point {i} truncated", file=path, offset=offset)
        record = _POINT_RECORD.unpack_from(data, offset)
        points[i] = record[1:4]
        offset += _POINT_RECORD.size + 8 * record[-1]
        if offset > len(data):
            raise InputError(f"track of point {i} runs past the end", file=path, offset=offset)
    _check_finite(points, path)
    return points


def _colmap_points_txt(path: Path) -> np.ndarray:
    rows = []
    text = read_regular(path, what="points3D.txt").decode("utf-8", errors="replace")
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        fields = line.split()
        try:
            rows.append([float(v) for v in fields[1:4]])
        except ValueError:
            raise InputError(f"line {number}: expected POINT3D_ID X Y Z ...", file=path,
                              offset=number) from None
        if len(rows[-1]) != 3:
            raise InputError(f"line {number}: expected POINT3D_ID X Y Z ...", file=path,
                              offset=number)
    points = np.asarray(rows, np.float64).reshape(-1, 3)
    _check_finite(points, path)
    return points


def random_points(cameras: list[Camera], count: int = RANDOM_POINT_COUNT, seed: int = 0
                  ) -> np.ndarray:
    """(count, 3) float64 points uniform in the ball the cameras look into.

    The ball's centre is the point nearest (least squares) to every camera's optical axis;
    its radius half the median camera distance to it.
    """
    if not cameras:
        raise InputError("random initial points need at least one camera", property="views")
    origins = np.stack([c.position for c in cameras])
    axes = np.stack([c.camera_to_world[:3, 2] for c in cameras])
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    # Least-squares point nearest all lines origin + t * axis.
    projectors = np.eye(3)[None] - axes[:, :, None] * axes[:, None, :]
    lhs = projectors.sum(axis=0)
    rhs = np.einsum("nij,nj->i", projectors, origins)
    if np.linalg.matrix_rank(lhs) < 3:
        centre = origins.mean(axis=0) + axes.mean(axis=0)
    else:
        centre = np.linalg.solve(lhs, rhs)
    radius = 0.5 * float(np.median(np.linalg.norm(origins - centre, axis=1)))
    rng = np.random.default_rng(seed)
    direction = rng.standard_normal((count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return centre + direction * (radius * rng.uniform(0, 1, (count, 1)) ** (1 / 3))


def find_initial_points(dataset: str | Path, cameras: list[Camera], *,
                        points: str | Path | None = None, seed: int = 0,
                        views: list | None = None) -> tuple[np.ndarray, str]:
    """The initial point cloud of a dataset and where it came from (module notes).

    Args:
        dataset: the dataset folder or camera file.
        cameras: the training cameras (for random points).
        points: a PLY the caller names (overrides everything).
        seed: seed of the random points.
        views: the training views (images and cameras) to triangulate from, or None.

    Returns:
        ((N, 3) float64 points, a short description of the source for the user).
    """
    if points is not None:
        return read_ply_points(points), str(points)
    camera_file = find_camera_file(Path(dataset))
    folder = camera_file.parent
    if camera_file.suffix == ".json":
        try:
            document = load_json(read_regular(camera_file, MAX_CAMERA_FILE_BYTES,
                                              what="a camera file"), file=camera_file)
        except InputError:
            document = None  # find_camera_file's reader reports what is wrong with it
        if isinstance(document, dict) and isinstance(document.get("ply_file_path"), str):
            candidate = folder / document["ply_file_path"]
            if candidate.is_file():
                return read_ply_points(candidate), str(candidate)
        if (folder / SCENE_FILE).is_file():
            return read_ply_points(folder / SCENE_FILE), str(folder / SCENE_FILE)
    for model in (camera_file, folder):
        if model.is_dir() and ((model / "points3D.bin").is_file()
                               or (model / "points3D.txt").is_file()):
            return read_colmap_points(model), str(model)
    why = "no training views to triangulate from"
    if views is not None and len(views) >= 2:
        from csgs_codec.train.sfm_points import MIN_POINTS, pycolmap_available, triangulate_views

        if not pycolmap_available():
            why = "pycolmap is not installed (pip install 'csgs[train]')"
        else:
            found = triangulate_views(views)
            if len(found.points) >= MIN_POINTS:
                how = "cached" if found.cached else "triangulated now"
                return found.points, (f"{len(found.points):,} points triangulated by pycolmap "
                                      f"from {len(views)} views ({how}: {found.folder})")
            why = f"pycolmap triangulated only {len(found.points)} points"
    warnings.warn(f"{dataset}: no initial points ({why}); starting from "
                  f"{RANDOM_POINT_COUNT:,} random points, which trains worse",
                  CsgsWarning, stacklevel=2)
    return random_points(cameras, seed=seed), f"{RANDOM_POINT_COUNT} random points"
