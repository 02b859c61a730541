"""Cameras from COLMAP sparse models, text (``cameras.txt``/``images.txt``) or binary (``.bin``).

COLMAP stores, per image, the world-to-camera rotation as a unit quaternion (qw, qx, qy, qz) and
the translation t, in the OpenCV camera convention, with pixel centres at integer + 0.5: the
same convention as :class:`Camera`. Intrinsics: PINHOLE and SIMPLE_PINHOLE are used as they
are; for the other models (radial, OpenCV, fisheye, ...) the focal lengths and principal point
are kept and the distortion is ignored, with one warning per file when it is not zero. Cameras
are returned sorted by image name.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from csgs_codec.errors import CsgsWarning, InputError, UnsupportedError
from csgs_codec.scene.camera import (
    MAX_CAMERA_FILE_BYTES,
    MAX_IMAGE_SIDE,
    Camera,
    intrinsics_problem,
)
from csgs_codec.untrusted import read_regular, refuse_non_regular

#: model id -> (name, parameter count, focal layout): "f" = one focal, "fxfy" = two.
COLMAP_MODELS = {
    0: ("SIMPLE_PINHOLE", 3, "f"),
    1: ("PINHOLE", 4, "fxfy"),
    2: ("SIMPLE_RADIAL", 4, "f"),
    3: ("RADIAL", 5, "f"),
    4: ("OPENCV", 8, "fxfy"),
    5: ("OPENCV_FISHEYE", 8, "fxfy"),
    6: ("FULL_OPENCV", 12, "fxfy"),
    7: ("FOV", 5, "fxfy"),
    8: ("SIMPLE_RADIAL_FISHEYE", 4, "f"),
    9: ("RADIAL_FISHEYE", 5, "f"),
    10: ("THIN_PRISM_FISHEYE", 12, "fxfy"),
}
_MODEL_IDS = {name: model_id for model_id, (name, _, _) in COLMAP_MODELS.items()}
_FISHEYE = {"OPENCV_FISHEYE", "SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE", "THIN_PRISM_FISHEYE"}
_POINT2D_BYTES = 24  # x, y float64 and point3D id int64


def is_colmap_path(path: Path) -> bool:
    """True when ``path`` is a COLMAP model folder or one of its cameras/images files."""
    return _model_files(path) is not None


def load_colmap_cameras(path: str | Path) -> list[Camera]:
    """Cameras of a COLMAP model: a folder (or ``sparse/0`` below it) or one of its files.

    Raises:
        InputError: missing file, a device or FIFO, malformed line or record (names the file
            and field).
        UnsupportedError: a camera model this loader does not know.
    """
    refuse_non_regular(path, directory_ok=True)
    files = _model_files(Path(path))
    if files is None:
        raise InputError("no COLMAP cameras + images files found", file=path)
    cameras_file, images_file, binary = files
    if binary:
        intrinsics = _read_cameras_bin(cameras_file)
        images = _read_images_bin(images_file)
    else:
        intrinsics = _read_cameras_txt(cameras_file)
        images = _read_images_txt(images_file)
    distorted = sorted({name for name, params in
                        ((COLMAP_MODELS[m][0], p) for m, _, _, p in intrinsics.values())
                        if _has_distortion(name, params)})
    if distorted:
        warnings.warn(f"{cameras_file}: distortion of camera model(s) {', '.join(distorted)} "
                      "ignored; cameras are treated as pinhole", CsgsWarning, stacklevel=2)
    cameras = []
    for name, qvec, tvec, camera_id in sorted(images, key=lambda image: image[0]):
        if camera_id not in intrinsics:
            raise InputError(f"image '{name}' refers to camera {camera_id}, which "
                             f"{cameras_file.name} does not define", file=images_file,
                             property="CAMERA_ID")
        model_id, width, height, params = intrinsics[camera_id]
        fx, fy, cx, cy = _pinhole(model_id, params)
        world_to_camera = np.eye(4)
        world_to_camera[:3, :3] = quaternion_to_matrix(qvec)
        world_to_camera[:3, 3] = tvec
        cameras.append(Camera(width, height, fx, fy, cx, cy, world_to_camera, name=name))
    if not cameras:
        raise InputError("no registered images", file=images_file)
    return cameras


def quaternion_to_matrix(qvec: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix of the quaternion (w, x, y, z), normalised first."""
    w, x, y, z = np.asarray(qvec, dtype=np.float64) / np.linalg.norm(qvec)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


# --------------------------------------------------------------------------- locating files
def colmap_model_files(path: Path) -> list[Path]:
    """The files of the COLMAP model ``path`` names (cameras, images and, when present,
    points3D); [] when ``path`` is no COLMAP model. Nothing is read."""
    files = _model_files(Path(path))
    if files is None:
        return []
    cameras_file, images_file, binary = files
    points = cameras_file.parent / f"points3D{'.bin' if binary else '.txt'}"
    return [cameras_file, images_file] + ([points] if points.is_file() else [])


def _model_files(path: Path) -> tuple[Path, Path, bool] | None:
    """(cameras file, images file, is_binary) for a model folder or one of its files."""
    if path.is_file():
        if path.name not in ("cameras.txt", "images.txt", "cameras.bin", "images.bin"):
            return None
        folder, suffix = path.parent, path.suffix
        files = folder / f"cameras{suffix}", folder / f"images{suffix}"
        return (*files, suffix == ".bin") if all(f.is_file() for f in files) else None
    if not path.is_dir():
        return None
    for folder in (path, path / "sparse" / "0", path / "sparse"):
        for suffix in (".bin", ".txt"):
            files = folder / f"cameras{suffix}", folder / f"images{suffix}"
            if all(f.is_file() for f in files):
                return (*files, suffix == ".bin")
    return None


def _read_bytes(path: Path) -> bytes:
    """The bytes of the regular file ``path``, at most MAX_CAMERA_FILE_BYTES."""
    return read_regular(path, MAX_CAMERA_FILE_BYTES, what="a COLMAP file")


# --------------------------------------------------------------------------- intrinsics
def _pinhole(model_id: int, params: np.ndarray) -> tuple[float, float, float, float]:
    layout = COLMAP_MODELS[model_id][2]
    if layout == "f":
        return float(params[0]), float(params[0]), float(params[1]), float(params[2])
    return float(params[0]), float(params[1]), float(params[2]), float(params[3])


def _has_distortion(model_name: str, params: np.ndarray) -> bool:
    if model_name in _FISHEYE:
        return True
    first_distortion = 3 if COLMAP_MODELS[_MODEL_IDS[model_name]][2] == "f" else 4
    return bool(np.any(params[first_distortion:] != 0))


def _check_intrinsics(camera_id: int, model_id: int, width: int, height: int,
                      params: np.ndarray, source: Path) -> None:
    where = f"camera {camera_id}"
    if not (0 < width <= MAX_IMAGE_SIDE and 0 < height <= MAX_IMAGE_SIDE):
        raise InputError(f"{where}: image size {width}x{height} out of range 1..{MAX_IMAGE_SIDE}",
                         file=source, property="WIDTH/HEIGHT")
    if not np.all(np.isfinite(params)):
        raise InputError(f"{where}: non-finite parameter", file=source, property="PARAMS")
    fx, fy, cx, cy = _pinhole(model_id, params)
    if fx <= 0 or fy <= 0:
        raise InputError(f"{where}: focal length must be positive", file=source,
                         property="PARAMS")
    problem = intrinsics_problem(width, height, fx, fy, cx, cy)
    if problem is not None:
        raise InputError(f"{where}: {problem[1]}", file=source,
                         property=f"PARAMS ({problem[0]})")


def _read_cameras_txt(path: Path) -> dict[int, tuple[int, int, int, np.ndarray]]:
    out = {}
    for line_number, fields in _data_lines(path):
        if len(fields) < 4:
            raise InputError(f"line {line_number}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS",
                             file=path, property="CAMERA_ID")
        camera_id = _int(fields[0], path, line_number, "CAMERA_ID")
        if fields[1] not in _MODEL_IDS:
            raise UnsupportedError(f"line {line_number}: camera model '{fields[1]}' is not "
                                   f"supported (known: {', '.join(_MODEL_IDS)})", file=path,
                                   property="MODEL")
        model_id = _MODEL_IDS[fields[1]]
        width = _int(fields[2], path, line_number, "WIDTH")
        height = _int(fields[3], path, line_number, "HEIGHT")
        expected = COLMAP_MODELS[model_id][1]
        if len(fields) - 4 != expected:
            raise InputError(f"line {line_number}: {fields[1]} takes {expected} parameters, "
                             f"got {len(fields) - 4}", file=path, property="PARAMS")
        params = np.array([_float(v, path, line_number, "PARAMS") for v in fields[4:]])
        _check_intrinsics(camera_id, model_id, width, height, params, path)
        out[camera_id] = (model_id, width, height, params)
    return out


def _read_images_txt(path: Path) -> list[tuple[str, np.ndarray, np.ndarray, int]]:
    """(name, qvec, tvec, camera_id) per image; each image line is followed by a points line."""
    images = []
    try:
        lines = _read_bytes(path).decode("utf-8").splitlines()
    except UnicodeDecodeError:
        raise InputError("not UTF-8 text", file=path) from None
    index = 0
    while index < len(lines):
        line = lines[index].strip()
        index += 1
        if not line or line.startswith("#"):
            continue
        fields = line.split()
        if len(fields) < 10:
            raise InputError(f"line {index}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID "
                             "NAME", file=path, property="NAME")
        numbers = [_float(v, path, index, "QW..TZ") for v in fields[1:8]]
        qvec, tvec = np.array(numbers[:4]), np.array(numbers[4:])
        if not np.linalg.norm(qvec) > 0:
            raise InputError(f"line {index}: zero quaternion", file=path, property="QW..QZ")
        camera_id = _int(fields[8], path, index, "CAMERA_ID")
        images.append((" ".join(fields[9:]), qvec, tvec, camera_id))
        index += 1  # the POINTS2D line that follows every image line
    return images


def _data_lines(path: Path):
    try:
        text = _read_bytes(path).decode("utf-8")
    except UnicodeDecodeError:
        raise InputError("not UTF-8 text", file=path) from None
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if line and not line.startswith("#"):
            yield number, line.split()


def _int(text: str, path: Path, line: int, field: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise InputError(f"line {line}: expected an integer, got {text!r}", file=path,
                         property=field) from None


def _float(text: str, path: Path, line: int, field: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"line {line}: expected a number, got {text!r}", file=path,
                         property=field) from None
    if not np.isfinite(value):
        raise InputError(f"line {line}: non-finite value {text!r}", file=path, property=field)
    return value


# --------------------------------------------------------------------------- binary
class _BinaryReader:
    """Bounds-checked little-endian reads over a whole file held in memory."""

    def __init__(self, data: bytes, source: Path) -> None:
        self.data, self.source, self.offset = data, source, 0

    def take(self, fmt: str, field: str) -> tuple:
        size = struct.calcsize("<" + fmt)
        if self.offset + size > len(self.data):
            raise InputError(f"file ends inside {field}", file=self.source, property=field,
                             offset=self.offset)
        values = struct.unpack_from("<" + fmt, self.data, self.offset)
        self.offset += size
        return values

    def skip(self, size: int, field: str) -> None:
        if size < 0 or self.offset + size > len(self.data):
            raise InputError(f"file ends inside {field}", file=self.source, property=field,
                             offset=self.offset)
        self.offset += size

    def name(self, field: str) -> str:
        end = self.data.find(b"\0", self.offset)
        if end < 0:
            raise InputError("unterminated image name", file=self.source, property=field,
                             offset=self.offset)
        raw, self.offset = self.data[self.offset:end], end + 1
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            raise InputError("image name is not UTF-8", file=self.source, property=field,
                             offset=self.offset) from None

    def count(self, record_bytes: int, field: str) -> int:
        (count,) = self.take("Q", field)
        if count * record_bytes > len(self.data) - self.offset:
            raise InputError(f"count {count} exceeds what the file holds", file=self.source,
                             property=field, offset=self.offset - 8)
        return count


def _read_cameras_bin(path: Path) -> dict[int, tuple[int, int, int, np.ndarray]]:
    reader = _BinaryReader(_read_bytes(path), path)
    out = {}
    for _ in range(reader.count(24, "num_cameras")):
        start = reader.offset
        camera_id, model_id, width, height = reader.take("iiQQ", "camera")
        if model_id not in COLMAP_MODELS:
            raise UnsupportedError(f"camera model id {model_id} is not supported",
                                   file=path, property="model_id", offset=start + 4)
        params = np.array(reader.take("d" * COLMAP_MODELS[model_id][1], "params"))
        _check_intrinsics(camera_id, model_id, width, height, params, path)
        out[camera_id] = (model_id, width, height, params)
    if reader.offset != len(reader.data):
        raise InputError("trailing bytes after the last camera", file=path,
                         offset=reader.offset)
    return out


def _read_images_bin(path: Path) -> list[tuple[str, np.ndarray, np.ndarray, int]]:
    reader = _BinaryReader(_read_bytes(path), path)
    images = []
    for _ in range(reader.count(69, "num_reg_images")):
        start = reader.offset
        values = reader.take("i7di", "image")
        qvec, tvec = np.array(values[1:5]), np.array(values[5:8])
        if not (np.all(np.isfinite(values[1:8])) and np.linalg.norm(qvec) > 0):
            raise InputError("non-finite pose or zero quaternion", file=path,
                             property="qvec/tvec", offset=start + 4)
        name = reader.name("name")
        points = reader.count(_POINT2D_BYTES, "num_points2D")
        reader.skip(points * _POINT2D_BYTES, "points2D")
        images.append((name, qvec, tvec, values[8]))
    if reader.offset != len(reader.data):
        raise InputError("trailing bytes after the last image", file=path, offset=reader.offset)
    return images
