"""PlayCanvas SOG (v1 and v2): attributes quantized into lossless WebP images plus a
``meta.json``, as a ``.sog`` zip or a folder.

Images hold one Gaussian per pixel in row-major order (``meta.json``: see
github.com/playcanvas/splat-transform, ``readers/read-sog.ts`` and ``read-sog-v1.ts``):

* ``means_l`` / ``means_u``: low and high bytes of 16-bit positions over the ``mins`` ..
  ``maxs`` box of sign(x) log(|x| + 1);
* ``quats``: three smallest quaternion components as (v sqrt 2 + 1) / 2 in RGB, and 252 +
  the index (w, x, y, z) of the largest one in A;
* ``scales``, ``sh0``: v2 indexes 256-entry codebooks (log scale; SH DC) with each byte and
  keeps alpha in ``sh0``'s A; v1 spreads each channel linearly over its ``mins`` .. ``maxs``
  (``sh0``'s A then spans opacity logits);
* ``shN_labels`` (16-bit palette index in R, G) and ``shN_centroids`` (palette rows of 64
  entries, one pixel per SH coefficient, RGB as codebook indices in v2 or bytes over the
  scalar ``mins`` .. ``maxs`` in v1).

WebP decoding needs Pillow (the ``formats`` extra).
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.interchange.binary import (
    SH_COEFFS,
    alpha_to_logit,
    from_smallest_three,
    optional_module,
)
from csgs_codec.interchange.source import SceneSource
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.untrusted import load_json, open_regular, read_regular

ZIP_MAGIC = b"PK\x03\x04"
MAX_META_BYTES = 16 << 20
#: Largest image or zip member accepted, bytes once decoded.
MAX_MEMBER_BYTES = 1 << 30
MAX_GAUSSIANS = 1 << 27
#: Largest ratio of a zip member's declared size to its compressed size (deflate reaches
#: about 1032), and of an image's decoded RGBA bytes to its file's (beyond
#: IMAGE_ALLOWANCE): more is refused before anything is inflated or decoded. Real SOG
#: images, noisy attribute data, decode to a few times their size.
MAX_RATIO = 1100
IMAGE_ALLOWANCE = 1 << 20
V1_CENTROID_WIDTHS = {192: 1, 512: 2, 960: 3}


class _Files:
    """The members of a SOG: a zip's entries or a folder's files, read with size limits.

    Use as a context manager: it closes the zip archive it opened.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.zip = None
        if path.is_dir():
            self.folder = path
        elif path.name == "meta.json":
            self.folder = path.parent
        else:
            self.folder = None
            handle = open_regular(path)
            try:
                self.zip = zipfile.ZipFile(handle)
            except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
                handle.close()
                raise InputError(f"not a readable zip archive ({exc})", file=path,
                                 offset=0) from None
            self._handle = handle

    def __enter__(self) -> _Files:
        return self

    def __exit__(self, *exc) -> None:
        if self.zip is not None:
            self.zip.close()
            self._handle.close()

    def read(self, name: str, limit: int = MAX_MEMBER_BYTES) -> bytes:
        """The bytes of member ``name``: at most ``limit``, and for a zip member at most its
        declared size, itself at most :data:`MAX_RATIO` times its compressed size."""
        if "/" in name or "\\" in name or name.startswith(".") or "\0" in name:
            raise InputError(f"meta.json names the file {name!r}, which is not a plain file "
                             "name", file=self.path)
        if self.zip is None:
            return read_regular(self.folder / name, limit, what="a SOG member")
        try:
            info = self.zip.getinfo(name)
        except KeyError:
            raise InputError(f"the archive has no {name}", file=self.path) from None
        if info.file_size > limit or info.file_size > MAX_RATIO * max(info.compress_size, 1):
            raise InputError(f"{name} declares {info.file_size:,} bytes from "
                             f"{info.compress_size:,} compressed (limits: {limit:,} bytes, "
                             f"{MAX_RATIO} times the compressed size)", file=self.path,
                             offset=info.header_offset)
        try:
            # Read no more than the declared size, whatever the compressed stream holds.
            with self.zip.open(info) as member:
                data = member.read(info.file_size + 1)
        except Exception as exc:  # zipfile raises many types for a corrupt member (zlib.error...)
            raise InputError(f"{name}: corrupt zip member ({exc})", file=self.path,
                             offset=info.header_offset) from None
        if len(data) != info.file_size:
            raise InputError(f"{name} holds {len(data):,} bytes, {info.file_size:,} declared",
                             file=self.path, offset=info.header_offset)
        return data


def read_sog(path: str | Path) -> tuple[GaussianScene, SceneSource]:
    """Read a SOG: a ``.sog`` zip, a folder holding ``meta.json`` or that ``meta.json``.

    Raises:
        InputError: a missing or malformed ``meta.json`` entry (named as the property), an
            image missing, too small for the count or not decodable; a member (or the
            ``.sog``) that is no regular file.
        UnsupportedError: an unknown meta version; Pillow missing.
    """
    path = Path(path)
    with _Files(path) as files:
        meta = load_json(files.read("meta.json", MAX_META_BYTES), file=path, what="meta.json")
        if not isinstance(meta, dict):
            raise InputError("meta.json is not a JSON object", file=path)
        version = meta.get("version")
        if version is None:
            scene = _read_v1(meta, files, path)
            label_version = "1"
        elif version == 2:
            scene = _read_v2(meta, files, path)
            label_version = "2"
        else:
            raise UnsupportedError(f"SOG meta.json version {version!r} (csgs reads 1 and 2)",
                                   file=path, property="version")
        details = {"container": "zip" if files.zip else "folder"}
    return scene, SceneSource("sog", "PlayCanvas SOG", label_version, lossy=True,
                              details=details)


# --------------------------------------------------------------------------- meta access
def _get(meta: dict, key: str, path: Path, kind=None):
    node = meta
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            raise InputError("missing in meta.json", file=path, property=key)
        node = node[part]
    if kind is not None and not isinstance(node, kind):
        raise InputError(f"expected {kind.__name__ if isinstance(kind, type) else 'number'} "
                         "in meta.json", file=path, property=key)
    return node


def _floats(meta: dict, key: str, path: Path, length: int | None) -> np.ndarray:
    values = _get(meta, key, path, list)
    try:
        out = np.array(values, np.float64)
    except (TypeError, ValueError):
        raise InputError("expected numbers in meta.json", file=path, property=key) from None
    if out.ndim != 1 or (length is not None and len(out) != length) or not np.all(
            np.isfinite(out)):
        raise InputError(f"expected {length or 'some'} finite numbers in meta.json",
                         file=path, property=key)
    return out


def _count(value, path: Path, key: str) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 < value <= MAX_GAUSSIANS:
        raise InputError(f"Gaussian count {value!r} is not in 1..{MAX_GAUSSIANS}", file=path,
                         property=key)
    return value


def _image(files: _Files, meta: dict, key: str, index: int, path: Path, minimum: int,
           maximum: int) -> tuple[np.ndarray, int, int]:
    """(pixels (W*H, 4) uint8 row-major, W, H) of the ``index``-th file of ``key``."""
    names = _get(meta, f"{key}.files", path, list)
    if len(names) <= index or not isinstance(names[index], str):
        raise InputError(f"expected a file name at index {index}", file=path,
                         property=f"{key}.files")
    image_module = optional_module("PIL.Image", "reading SOG (WebP images)")
    data = files.read(names[index])
    try:
        with image_module.open(io.BytesIO(data)) as image:
            width, height = image.size
            if not minimum <= width * height <= maximum:
                raise InputError(f"{names[index]} is {width}x{height}; it must hold "
                                 f"{minimum:,} to {maximum:,} pixels", file=path,
                                 property=f"{key}.files")
            if 4 * width * height > MAX_RATIO * len(data) + IMAGE_ALLOWANCE:
                raise InputError(f"{names[index]} is {width}x{height} pixels in {len(data):,} "
                                 f"bytes: more than {MAX_RATIO} times its size once decoded",
                                 file=path, property=f"{key}.files")
            pixels = np.asarray(image.convert("RGBA"), np.uint8).reshape(-1, 4)
    except InputError:
        raise
    except Exception as exc:  # Pillow raises many types for undecodable data
        raise InputError(f"{names[index]} is not a decodable image ({exc})", file=path,
                         property=f"{key}.files") from None
    return pixels, width, height


def _positions(meta, files, path, n) -> np.ndarray:
    limit = 2 * n + (1 << 16)
    lo, _, _ = _image(files, meta, "means", 0, path, n, limit)
    hi, _, _ = _image(files, meta, "means", 1, path, n, limit)
    q = lo[:n, :3].astype(np.float64) + 256.0 * hi[:n, :3]
    mins = _floats(meta, "means.mins", path, 3)
    span = _floats(meta, "means.maxs", path, 3) - mins
    span = np.where(span == 0, 1.0, span)
    v = mins + span * (q / 65535.0)
    return (np.sign(v) * np.expm1(np.abs(v))).astype(np.float32)


def _rotations(meta, files, path, n) -> np.ndarray:
    pixels, _, _ = _image(files, meta, "quats", 0, path, n, 2 * n + (1 << 16))
    pixels = pixels[:n]
    others = (pixels[:, :3].astype(np.float64) / 255.0 * 2.0 - 1.0) / np.sqrt(2.0)
    tag = pixels[:, 3].astype(np.int64)
    valid = (tag >= 252) & (tag <= 255)
    largest = np.where(valid, tag - 252, 0)
    out = from_smallest_three(largest, others)
    out[~valid] = (1.0, 0.0, 0.0, 0.0)
    return out.astype(np.float32)


def _codebook(meta, key, path) -> np.ndarray:
    book = _floats(meta, f"{key}.codebook", path, None)
    if not 1 <= len(book) <= 256:
        raise InputError(f"a codebook of {len(book)} entries (1-256 expected)", file=path,
                         property=f"{key}.codebook")
    return np.concatenate([book, np.zeros(256 - len(book))])


def _read_v2(meta: dict, files: _Files, path: Path) -> GaussianScene:
    n = _count(meta.get("count"), path, "count")
    limit = 2 * n + (1 << 16)
    scales, _, _ = _image(files, meta, "scales", 0, path, n, limit)
    sh0, _, _ = _image(files, meta, "sh0", 0, path, n, limit)
    scale_book, color_book = _codebook(meta, "scales", path), _codebook(meta, "sh0", path)
    sh_rest = np.zeros((n, 0, 3), np.float32)
    if isinstance(meta.get("shN"), dict):
        bands = _get(meta, "shN.bands", path, int)
        if bands not in (1, 2, 3):
            raise InputError(f"{bands} SH bands (1-3 expected)", file=path,
                             property="shN.bands")
        palette = _get(meta, "shN.count", path, int)
        if not 0 < palette <= 1 << 16:
            raise InputError(f"palette of {palette} entries (1-65536 expected)", file=path,
                             property="shN.count")
        book = _codebook(meta, "shN", path)
        sh_rest = _palette_sh(meta, files, path, n, bands, palette, lambda b: book[b])
    return GaussianScene(
        positions=_positions(meta, files, path, n),
        sh_dc=color_book[sh0[:n, :3]].astype(np.float32),
        sh_rest=sh_rest,
        opacity=alpha_to_logit(sh0[:n, 3] / 255.0),
        scales=scale_book[scales[:n, :3]].astype(np.float32),
        rotations=_rotations(meta, files, path, n),
    )


def _palette_sh(meta, files, path, n, bands, palette, dequantize) -> np.ndarray:
    coeffs = SH_COEFFS[bands]
    labels, _, _ = _image(files, meta, "shN", 1, path, n, 2 * n + (1 << 16))
    rows = -(-palette // 64)
    centroids, width, height = _image(files, meta, "shN", 0, path, 1, 64 * coeffs * (rows + 1))
    if width != 64 * coeffs:
        raise InputError(f"shN centroids are {width} pixels wide, {64 * coeffs} expected "
                         f"for {bands} bands", file=path, property="shN.files")
    label = labels[:n, 0].astype(np.int64) | (labels[:n, 1].astype(np.int64) << 8)
    valid = label < min(palette, (width // coeffs) * height)
    label = np.where(valid, label, 0)
    pixel = (label // 64)[:, None] * width + (label % 64)[:, None] * coeffs + np.arange(coeffs)
    values = dequantize(centroids[pixel, :3])  # (n, coeffs, 3): coefficient-major, RGB
    values = np.where(valid[:, None, None], values, 0.0)
    return values.astype(np.float32)


def _read_v1(meta: dict, files: _Files, path: Path) -> GaussianScene:
    shape = _get(meta, "means.shape", path, list)
    if not shape:
        raise InputError("expected [count, 3]", file=path, property="means.shape")
    n = _count(shape[0], path, "means.shape")
    limit = 2 * n + (1 << 16)
    scales, _, _ = _image(files, meta, "scales", 0, path, n, limit)
    sh0, _, _ = _image(files, meta, "sh0", 0, path, n, limit)
    s_min = _floats(meta, "scales.mins", path, 3)
    s_span = _floats(meta, "scales.maxs", path, 3) - s_min
    c_min = _floats(meta, "sh0.mins", path, 4)
    c_span = _floats(meta, "sh0.maxs", path, 4) - c_min
    color = c_min + c_span * (sh0[:n].astype(np.float64) / 255.0)
    sh_rest = np.zeros((n, 0, 3), np.float32)
    if isinstance(meta.get("shN"), dict):
        lo = _get(meta, "shN.mins", path, (int, float))
        hi = _get(meta, "shN.maxs", path, (int, float))
        names = _get(meta, "shN.files", path, list)
        if len(names) < 2 or not isinstance(names[0], str):
            raise InputError("expected centroid and label files", file=path,
                             property="shN.files")
        with _Probe(files, names[0], path) as size:
            width, height = size
        bands = V1_CENTROID_WIDTHS.get(width)
        if bands is None:
            raise InputError(f"shN centroids are {width} pixels wide (192, 512 or 960 "
                             "expected)", file=path, property="shN.files")
        palette = (width // SH_COEFFS[bands]) * height
        sh_rest = _palette_sh(meta, files, path, n, bands, palette,
                              lambda b: lo + (hi - lo) * (b / 255.0))
    return GaussianScene(
        positions=_positions(meta, files, path, n),
        sh_dc=color[:, :3].astype(np.float32),
        sh_rest=sh_rest,
        opacity=color[:, 3].astype(np.float32),
        scales=(s_min + s_span * (scales[:n, :3] / 255.0)).astype(np.float32),
        rotations=_rotations(meta, files, path, n),
    )


class _Probe:
    """Context manager giving an image's (width, height) without decoding its pixels."""

    def __init__(self, files: _Files, name: str, path: Path) -> None:
        self.files, self.name, self.path = files, name, path
        self.image = None

    def __enter__(self) -> tuple[int, int]:
        image_module = optional_module("PIL.Image", "reading SOG (WebP images)")
        try:
            self.image = image_module.open(io.BytesIO(self.files.read(self.name)))
            return self.image.size
        except InputError:
            raise
        except Exception as exc:
            raise InputError(f"{self.name} is not a decodable image ({exc})", file=self.path,
                             property="shN.files") from None

    def __exit__(self, *exc) -> None:
        if self.image is not None:
            self.image.close()
