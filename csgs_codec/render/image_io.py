"""Saving rendered images as 8-bit PNG files."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError


def png_bytes(image: np.ndarray) -> bytes:
    """PNG encoding of a float (H, W, 3) or (H, W) image: clipped to [0, 1], 8-bit rounded."""
    from PIL import Image

    array = np.asarray(image, dtype=np.float32)
    if array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[2] not in (1, 3, 4)):
        raise InputError(f"expected an (H, W), (H, W, 3) or (H, W, 4) image, got {array.shape}")
    pixels = np.round(np.clip(array, 0.0, 1.0) * 255.0).astype(np.uint8)
    if pixels.ndim == 3 and pixels.shape[2] == 1:
        pixels = pixels[..., 0]
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()


def save_png(image: np.ndarray, path: str | Path) -> None:
    """Write ``image`` (see :func:`png_bytes`) to ``path`` through a temporary file."""
    from csgs_codec.atomic_write import write_atomically

    write_atomically(path, png_bytes(image))


def load_png(path: str | Path) -> np.ndarray:
    """(H, W, 3) float32 image in [0, 1] from an 8-bit image file."""
    from PIL import Image

    try:
        with Image.open(path) as handle:
            pixels = np.asarray(handle.convert("RGB"), dtype=np.float32)
    except OSError as exc:
        raise InputError(f"cannot read image: {exc}", file=path) from None
    return pixels / 255.0
