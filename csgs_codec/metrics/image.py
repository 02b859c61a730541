"""Image quality metrics on float RGB images in [0, 1]: PSNR, SSIM and foreground PSNR.

Images are (H, W, 3) (or (H, W)) arrays; they are compared in float64. Scores follow the usual
definitions so figures are comparable with the 3DGS literature:

* PSNR = 10 log10(1 / MSE) in dB, infinite for identical images.
* SSIM (Wang et al. 2004): 11x11 Gaussian window with sigma 1.5, C1 = (0.01)^2, C2 = (0.03)^2,
  computed per channel over the windows that fit inside the image ("valid" filtering, no
  padding), averaged over windows and channels. Images smaller than the window are scored on
  the whole image as one window.
* foreground PSNR: PSNR over the pixels where a mask (the original render's accumulated
  opacity > 0.05, see docs/design.md,
  'Measuring quality') is set, all channels.
"""

from __future__ import annotations

import math

import numpy as np

from csgs_codec.errors import InputError

#: Accumulated opacity above which a pixel of the reference render counts as foreground.
FOREGROUND_ALPHA = 0.05


def psnr(reference: np.ndarray, candidate: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB of two [0, 1] images of the same shape; inf if equal."""
    a, b = _pair(reference, candidate)
    return psnr_from_mse(float(np.mean((a - b) ** 2)))


def foreground_psnr(reference: np.ndarray, candidate: np.ndarray, mask: np.ndarray) -> float:
    """PSNR in dB over the pixels where ``mask`` (H, W) bool is set; nan when none is.

    Args:
        reference, candidate: (H, W, C) or (H, W) images in [0, 1].
        mask: (H, W) boolean foreground mask, e.g. ``alpha > FOREGROUND_ALPHA``.
    """
    a, b = _pair(reference, candidate)
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != a.shape[:2]:
        raise InputError(f"mask shape {mask.shape} does not match image shape {a.shape[:2]}")
    if not mask.any():
        return float("nan")
    return psnr_from_mse(float(np.mean((a[mask] - b[mask]) ** 2)))


def foreground_mask(alpha: np.ndarray, threshold: float = FOREGROUND_ALPHA) -> np.ndarray:
    """(H, W) bool: pixels whose accumulated opacity ``alpha`` (H, W) exceeds ``threshold``."""
    return np.asarray(alpha) > threshold


def ssim(reference: np.ndarray, candidate: np.ndarray) -> float:
    """Structural similarity of two [0, 1] images (H, W, C) or (H, W); 1.0 when equal
    (:mod:`csgs_codec.metrics.ssim`, evaluated in float64 without gradients)."""
    import torch

    from csgs_codec.metrics.ssim import ssim as ssim_torch

    a, b = _pair(reference, candidate)
    with torch.no_grad():
        return float(ssim_torch(torch.from_numpy(a), torch.from_numpy(b)))


def _pair(reference: np.ndarray, candidate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(reference, dtype=np.float64)
    b = np.asarray(candidate, dtype=np.float64)
    if a.shape != b.shape:
        raise InputError(f"image shapes differ: {a.shape} vs {b.shape}")
    if a.ndim not in (2, 3) or a.size == 0:
        raise InputError(f"expected a non-empty (H, W) or (H, W, C) image, got {a.shape}")
    return a, b


def psnr_from_mse(mse: float) -> float:
    """PSNR in dB of images in [0, 1] whose mean squared error is ``mse``; inf for 0."""
    return math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)
