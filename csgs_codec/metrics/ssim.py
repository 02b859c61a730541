"""Structural similarity (SSIM), the one implementation: differentiable, in torch.

Wang et al.'s definition as 3DGS uses it: an 11x11 Gaussian window (sigma 1.5), 'valid'
filtering (no padding), C1 = 0.01^2 and C2 = 0.03^2 for images in [0, 1], the mean of the
per-pixel map over pixels and channels; an image smaller than the window is scored as one
window over the whole image. Training takes it as a loss term
(:func:`csgs_codec.train.losses.photometric_loss`); :func:`csgs_codec.metrics.image.ssim`
evaluates it on numpy images.
"""

from __future__ import annotations

import torch

from csgs_codec.errors import InputError

SSIM_WINDOW = 11
SSIM_SIGMA = 1.5
SSIM_C1 = 0.01**2
SSIM_C2 = 0.03**2


def _gaussian_taps(dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """The [SSIM_WINDOW] Gaussian window on ``device``, computed in float64 on the CPU so
    that every device gets the same taps."""
    x = torch.arange(SSIM_WINDOW, dtype=torch.float64, device="cpu") - (SSIM_WINDOW - 1) / 2
    taps = torch.exp(-0.5 * (x / SSIM_SIGMA) ** 2)
    return (taps / taps.sum()).to(dtype=dtype, device=device)


def _valid_filter(planes: torch.Tensor, taps: torch.Tensor) -> torch.Tensor:
    """[P, H, W] -> [P, H - k + 1, W - k + 1]: separable 'valid' filtering (rows, then columns)."""
    k = taps.numel()
    x = planes[:, None]
    x = torch.nn.functional.conv2d(x, taps.view(1, 1, k, 1))
    x = torch.nn.functional.conv2d(x, taps.view(1, 1, 1, k))
    return x[:, 0]


def ssim(rendered: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Differentiable SSIM of two images (module notes): scalar, 1 for equal images.

    Args:
        rendered, target: [H, W, C] or [H, W] images in [0, 1], same shape and dtype.
    """
    if rendered.shape != target.shape:
        raise InputError(f"image shapes differ: {tuple(rendered.shape)} vs "
                         f"{tuple(target.shape)}", property="image")
    if rendered.ndim not in (2, 3) or rendered.numel() == 0:
        raise InputError(f"expected a non-empty [H, W] or [H, W, C] image, got "
                         f"{tuple(rendered.shape)}", property="image")
    a = rendered if rendered.ndim == 3 else rendered[..., None]
    b = target if target.ndim == 3 else target[..., None]
    a, b = a.permute(2, 0, 1), b.permute(2, 0, 1)  # [C, H, W]
    if min(a.shape[1], a.shape[2]) < SSIM_WINDOW:
        mu_a = a.mean(dim=(1, 2), keepdim=True)
        mu_b = b.mean(dim=(1, 2), keepdim=True)
        var_a = ((a - mu_a) ** 2).mean(dim=(1, 2))
        var_b = ((b - mu_b) ** 2).mean(dim=(1, 2))
        cov = ((a - mu_a) * (b - mu_b)).mean(dim=(1, 2))
        mu_a, mu_b = mu_a[:, 0, 0], mu_b[:, 0, 0]
    else:
        taps = _gaussian_taps(a.dtype, a.device)
        mu_a, mu_b = _valid_filter(a, taps), _valid_filter(b, taps)
        var_a = _valid_filter(a * a, taps) - mu_a**2
        var_b = _valid_filter(b * b, taps) - mu_b**2
        cov = _valid_filter(a * b, taps) - mu_a * mu_b
    score = ((2 * mu_a * mu_b + SSIM_C1) * (2 * cov + SSIM_C2)
             / ((mu_a**2 + mu_b**2 + SSIM_C1) * (var_a + var_b + SSIM_C2)))
    return score.mean()
