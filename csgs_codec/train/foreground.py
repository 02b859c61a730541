"""Foreground masks: train the object of a capture alone, its background kept transparent.

A foreground mask says, per pixel, whether the photo shows the object (distinct from the
instance masks of the semantic stages, which label objects). Files: any grey, palette or RGB
image, one per photo named by its stem; a pixel is foreground when its grey level is at least
half the range (8-bit: >= 128). A capture's ``masks/`` folder counts as foreground masks when
every one of its views' masks holds only the values 0 and 255 (:func:`is_binary_mask`).

With foreground masks, each training image is the photo composited over the training
background where the mask is 0 (so the photometric loss fits the object and asks for the
background colour elsewhere), and stage 1 adds :func:`background_alpha_loss`, which keeps the
rendered opacity there at 0 (so the background is transparent, not dark Gaussians).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from csgs_codec.errors import InputError

#: Grey level (of 255) at or above which a mask pixel is foreground.
FOREGROUND_LEVEL = 128


def _grey(path: Path) -> np.ndarray:
    """(H, W) uint8 grey levels of the mask image ``path`` (alpha ignored)."""
    from PIL import Image

    try:
        with Image.open(path) as handle:
            handle.load()
            if handle.mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
                return (np.asarray(handle, np.int64) >> 8).clip(0, 255).astype(np.uint8)
            return np.asarray(handle.convert("L"))
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise InputError(f"cannot read foreground mask: {exc}", file=path) from None


def read_foreground_mask(path: str | Path) -> np.ndarray:
    """(H, W) bool foreground of a mask image (module notes).

    Raises:
        InputError: naming the file when it cannot be read.
    """
    return _grey(Path(path)) >= FOREGROUND_LEVEL


def is_binary_mask(path: str | Path) -> bool:
    """True when the image ``path`` is one channel (grey or palette) holding only 0 and 255.

    Raises:
        InputError: naming the file when it cannot be read.
    """
    from PIL import Image

    path = Path(path)
    try:
        with Image.open(path) as handle:
            if handle.mode not in ("1", "L", "P"):
                return False
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise InputError(f"cannot read mask: {exc}", file=path) from None
    levels = np.unique(_grey(path))
    return bool(np.isin(levels, (0, 255)).all())


def composite_foreground(image: np.ndarray, foreground: np.ndarray,
                         background: tuple[float, float, float]) -> np.ndarray:
    """``image`` (H, W, 3) float32 with its pixels outside ``foreground`` (H, W) bool set to
    the RGB ``background`` in [0, 1]."""
    out = np.array(image, dtype=np.float32, copy=True)
    out[~foreground] = np.asarray(background, np.float32)
    return out


def background_alpha_loss(alpha: torch.Tensor, background: torch.Tensor) -> torch.Tensor:
    """Mean rendered opacity over the background pixels: scalar, 0 when there are none.

    Args:
        alpha: [H, W] accumulated opacity of a render, in [0, 1].
        background: [H, W] bool, True where the foreground mask says background (on
            ``alpha``'s device).
    """
    weight = background.to(alpha.dtype)
    return (alpha * weight).sum() / weight.sum().clamp_min(1.0)
