"""Reading training images and instance masks from files, and resizing them.

Images: any format Pillow reads; 8-bit channels are divided by 255, 16-bit grey by 65535.
Transparent images (RGBA, LA, palette with transparency) are composited over a background
color, as Blender-style datasets expect. Masks: one integer instance id per pixel, from
8/16/32-bit grey (alpha ignored) or palette PNGs (the palette index is the id) or RGB(A)
images (the id is ``r << 16 | g << 8 | b``, alpha ignored), as SAM exporters write them.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.untrusted import open_regular

#: Suffixes tried, in order, when an image is named without one.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".JPG", ".JPEG", ".PNG", ".tif", ".tiff", ".webp",
                  ".bmp")
_GREY_16_MODES = ("I;16", "I;16B", "I;16L", "I;16N")
#: Most pixels one training image or mask may hold (an 8K frame is 33 M): the size in its
#: header is checked before any pixel is decoded, so a small file claiming a huge image
#: never reaches memory.
MAX_IMAGE_PIXELS = 1 << 27
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def find_image(folder: Path, name: str) -> Path:
    """The file ``name`` under ``folder``, trying :data:`IMAGE_SUFFIXES` when it lacks one or
    when the named file is missing (COLMAP and INRIA files often drop the suffix).

    Raises:
        InputError: naming the expected path when no candidate exists, or when the system
            refuses the name (longer than the file system allows, say).
    """
    path = folder / name
    try:
        return _find_image(path)
    except OSError as exc:
        raise InputError(f"cannot look up the image: {exc.strerror or exc}", file=path) from None


def _find_image(path: Path) -> Path:
    if path.is_file():
        return path
    for suffix in IMAGE_SUFFIXES:
        candidate = path.with_name(path.name + suffix)
        if candidate.is_file():
            return candidate
        candidate = path.with_suffix(suffix) if path.suffix else None
        if candidate is not None and candidate.is_file():
            return candidate
    raise InputError("image file not found", file=path)


def check_png_chunks(path: Path) -> None:
    """Refuse a PNG whose chunk lengths run past the end of the file (no-op for other
    formats). Pillow reads an image chunk in one piece of its stated length, so an 89-byte
    file whose IDAT claims 512 MiB made it allocate 512 MiB before failing.

    Raises:
        InputError: naming the file, the chunk and its byte offset.
    """
    with open_regular(path) as handle:
        if handle.read(8) != PNG_SIGNATURE:
            return
        end = handle.seek(0, 2)
        offset = 8
        while offset + 8 <= end:
            handle.seek(offset)
            head = handle.read(8)
            length, kind = int.from_bytes(head[:4], "big"), head[4:8]
            if offset + 12 + length > end:
                name = kind.decode("latin1").encode("ascii", "backslashreplace").decode()
                raise InputError(f"PNG chunk '{name}' at byte {offset} claims {length:,} "
                                 f"bytes, past the end of the {end:,}-byte file", file=path)
            if kind == b"IEND":
                return
            offset += 12 + length


def _open(path: Path, size: tuple[int, int] | None = None, what: str = "image",
          owner: str = "its camera"):
    """The decoded image at ``path``; its header's (width, height) is checked against
    ``size`` (and :data:`MAX_IMAGE_PIXELS`) before the pixels are decoded."""
    from PIL import Image

    try:
        with warnings.catch_warnings():  # csgs's own bound below says it better
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            check_png_chunks(path)
            handle = Image.open(path)  # reads the header only
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise InputError(f"cannot read image: {exc}", file=path) from None
    try:
        width, height = handle.size
        if size is not None and (width, height) != tuple(size):
            raise InputError(f"{what} is {width}x{height} but {owner} is "
                             f"{size[0]}x{size[1]}", file=path)
        if width * height > MAX_IMAGE_PIXELS:
            raise InputError(f"{what} is {width}x{height}, more than the {MAX_IMAGE_PIXELS:,} "
                             "pixels csgs reads", file=path)
        handle.load()
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        handle.close()
        raise InputError(f"cannot read image: {exc}", file=path) from None
    except BaseException:
        handle.close()
        raise
    return handle


def read_image(path: str | Path, background: tuple[float, float, float] = (0.0, 0.0, 0.0),
               size: tuple[int, int] | None = None) -> np.ndarray:
    """(H, W, 3) float32 RGB in [0, 1] from an image file.

    Args:
        path: the image file.
        background: RGB in [0, 1] behind transparent pixels.
        size: the (width, height) its camera expects, checked before decoding, or None.

    Raises:
        InputError: naming the file when it cannot be read or its size is not ``size``.
    """
    path = Path(path)
    with _open(path, size) as handle:
        if handle.mode in _GREY_16_MODES or handle.mode == "I":
            grey = np.asarray(handle, dtype=np.float32) / 65535.0
            return np.repeat(np.clip(grey, 0.0, 1.0)[..., None], 3, axis=2)
        transparent = handle.mode in ("RGBA", "LA", "PA") or "transparency" in handle.info
        pixels = np.asarray(handle.convert("RGBA" if transparent else "RGB"), dtype=np.float32)
    pixels /= 255.0
    if not transparent:
        return np.ascontiguousarray(pixels)
    alpha = pixels[..., 3:4]
    bg = np.asarray(background, dtype=np.float32)
    return np.ascontiguousarray(pixels[..., :3] * alpha + bg * (1.0 - alpha))


def read_mask(path: str | Path, size: tuple[int, int] | None = None,
              owner: str = "its image") -> np.ndarray:
    """(H, W) int32 instance ids from a mask image (see the module notes for the encodings).

    Args:
        path: the mask file.
        size: the (width, height) of its image, checked before decoding, or None.
        owner: how the size error names the image (e.g. with its path).

    Raises:
        InputError: naming the file when it cannot be read, its size is not ``size``, or it
            holds no integer ids.
    """
    path = Path(path)
    with _open(path, size, "mask", owner) as handle:
        mode = handle.mode
        if mode in ("1", "L", "P", "I") or mode in _GREY_16_MODES:
            ids = np.asarray(handle).astype(np.int64)
        elif mode == "LA":  # grey + alpha: the grey value is the id
            ids = np.asarray(handle)[..., 0].astype(np.int64)
        elif mode in ("RGB", "RGBA"):
            rgb = np.asarray(handle.convert("RGB")).astype(np.int64)
            ids = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
        else:
            raise InputError(f"mask image mode {mode!r} holds no integer ids (use 8/16-bit "
                             "grey, palette or RGB PNG)", file=path)
    if ids.ndim != 2:
        raise InputError(f"mask must be one channel, got shape {ids.shape}", file=path)
    if ids.size and (ids.min() < np.iinfo(np.int32).min or ids.max() > np.iinfo(np.int32).max):
        raise InputError("mask ids exceed the int32 range", file=path)
    return ids.astype(np.int32)


def resize_image(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """``image`` (H, W, 3) float32 resized to (height, width, 3) with area averaging (box)."""
    from PIL import Image

    if (image.shape[1], image.shape[0]) == (width, height):
        return image
    channels = [np.asarray(Image.fromarray(np.ascontiguousarray(image[..., c], dtype=np.float32))
                           .resize((width, height), Image.Resampling.BOX))
                for c in range(image.shape[2])]
    return np.stack(channels, axis=2).astype(np.float32)


def resize_mask(mask: np.ndarray, width: int, height: int) -> np.ndarray:
    """``mask`` (H, W) int32 resized to (height, width) by nearest neighbour (ids stay ids)."""
    if (mask.shape[1], mask.shape[0]) == (width, height):
        return mask
    rows = np.minimum(((np.arange(height) + 0.5) * mask.shape[0] / height).astype(np.int64),
                      mask.shape[0] - 1)
    cols = np.minimum(((np.arange(width) + 0.5) * mask.shape[1] / width).astype(np.int64),
                      mask.shape[1] - 1)
    return np.ascontiguousarray(mask[rows[:, None], cols[None, :]])
