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

SSIM_WINDOW = 11
SSIM_SIGMA = 1.5
SSIM_C1 = 0.01**2
SSIM_C2 = 0.03**2
#: Accumulated opacity above which a pixel of the reference render counts as foreground.
FOREGROUND_ALPHA = 0.05


def psnr(reference: np.ndarray, candidate: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB of two [0, 1] images of the same shape; inf if equal."""
    a, b = _pair(reference, candidate)
    return _psnr_from_mse(float(np.mean((a - b) ** 2)))


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
    return _psnr_from_mse(float(np.mean((a[mask] - b[mask]) ** 2)))


def foreground_mask(alpha: np.ndarray, threshold: float = FOREGROUND_ALPHA) -> np.ndarray:
    """(H, W) bool: pixels whose accumulated opacity ``alpha`` (H, W) exceeds ``threshold``."""
    return np.asarray(alpha) > threshold


def ssim(reference: np.ndarray, candidate: np.ndarray) -> float:
    """Structural similarity of two [0, 1] images (H, W, C) or (H, W); 1.0 when equal."""
    a, b = _pair(reference, candidate)
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    if min(a.shape[0], a.shape[1]) < SSIM_WINDOW:
        return _ssim_single_window(a, b)
    kernel = gaussian_kernel_1d(SSIM_WINDOW, SSIM_SIGMA)
    mu_a, mu_b = _filter(a, kernel), _filter(b, kernel)
    var_a = _filter(a * a, kernel) - mu_a**2
    var_b = _filter(b * b, kernel) - mu_b**2
    cov = _filter(a * b, kernel) - mu_a * mu_b
    score = ((2 * mu_a * mu_b + SSIM_C1) * (2 * cov + SSIM_C2)
             / ((mu_a**2 + mu_b**2 + SSIM_C1) * (var_a + var_b + SSIM_C2)))
    return float(np.mean(score))


def gaussian_kernel_1d(size: int, sigma: float) -> np.ndarray:
    """(size,) float64 normalised Gaussian weights centred on the middle tap."""
    x = np.arange(size, dtype=np.float64) - (size - 1) / 2
    weights = np.exp(-0.5 * (x / sigma) ** 2)
    return weights / weights.sum()


def _filter(image: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Separable 'valid' filtering of (H, W, C) by ``kernel`` along H then W."""
    k = len(kernel)
    rows = sum(kernel[i] * image[i:image.shape[0] - k + 1 + i] for i in range(k))
    return sum(kernel[j] * rows[:, j:rows.shape[1] - k + 1 + j] for j in range(k))


def _ssim_single_window(a: np.ndarray, b: np.ndarray) -> float:
    scores = []
    for c in range(a.shape[2]):
        x, y = a[..., c].ravel(), b[..., c].ravel()
        mx, my = x.mean(), y.mean()
        cov = np.mean((x - mx) * (y - my))
        scores.append((2 * mx * my + SSIM_C1) * (2 * cov + SSIM_C2)
                      / ((mx**2 + my**2 + SSIM_C1) * (x.var() + y.var() + SSIM_C2)))
    return float(np.mean(scores))


def _pair(reference: np.ndarray, candidate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(reference, dtype=np.float64)
    b = np.asarray(candidate, dtype=np.float64)
    if a.shape != b.shape:
        raise InputError(f"image shapes differ: {a.shape} vs {b.shape}")
    if a.ndim not in (2, 3) or a.size == 0:
        raise InputError(f"expected a non-empty (H, W) or (H, W, C) image, got {a.shape}")
    return a, b


def _psnr_from_mse(mse: float) -> float:
    return math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)
