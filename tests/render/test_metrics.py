"""PSNR, SSIM and foreground PSNR follow their definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.metrics.image import foreground_mask, foreground_psnr, psnr, ssim
from csgs_codec.metrics.ssim import SSIM_C1, SSIM_C2


def noise_image(shape=(40, 50, 3), seed=0):
    return np.random.default_rng(seed).uniform(0, 1, size=shape).astype(np.float32)


def test_psnr_of_identical_images_is_infinite():
    image = noise_image()
    assert psnr(image, image.copy()) == math.inf


def test_psnr_of_constant_offset_is_minus_twenty_log_offset():
    image = noise_image() * 0.5
    assert psnr(image, image + 0.1) == pytest.approx(20.0, abs=1e-5)
    assert psnr(image, image + 0.01) == pytest.approx(40.0, abs=1e-4)


def test_ssim_of_identical_images_is_one():
    image = noise_image()
    assert ssim(image, image.copy()) == pytest.approx(1.0, abs=1e-12)


def test_ssim_of_flat_images_is_the_luminance_term():
    a, b = np.full((30, 30, 3), 0.2), np.full((30, 30, 3), 0.6)
    expected = (2 * 0.2 * 0.6 + SSIM_C1) / (0.2**2 + 0.6**2 + SSIM_C1)
    assert ssim(a, b) == pytest.approx(expected, rel=1e-9)


def test_ssim_uses_an_11x11_gaussian_window_with_sigma_1_5():
    a, b = noise_image((11, 11, 1), 1)[..., 0], noise_image((11, 11, 1), 2)[..., 0]
    a, b = a.astype(np.float64), b.astype(np.float64)
    x = np.arange(11) - 5
    w = np.exp(-(x[:, None] ** 2 + x[None, :] ** 2) / (2 * 1.5**2))
    w /= w.sum()
    ma, mb = (w * a).sum(), (w * b).sum()
    va, vb = (w * a * a).sum() - ma**2, (w * b * b).sum() - mb**2
    cov = (w * a * b).sum() - ma * mb
    expected = ((2 * ma * mb + SSIM_C1) * (2 * cov + SSIM_C2)
                / ((ma**2 + mb**2 + SSIM_C1) * (va + vb + SSIM_C2)))
    assert ssim(a, b) == pytest.approx(expected, rel=1e-9)


def windowed_ssim_map(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """SSIM of every 11x11 window of two 2-D images, written out window by window (float64)."""
    x = np.arange(11) - 5
    w = np.exp(-(x[:, None] ** 2 + x[None, :] ** 2) / (2 * 1.5**2))
    w /= w.sum()
    win = np.lib.stride_tricks.sliding_window_view
    wa, wb = win(a, (11, 11)), win(b, (11, 11))
    ma, mb = (w * wa).sum((-1, -2)), (w * wb).sum((-1, -2))
    va = (w * wa * wa).sum((-1, -2)) - ma**2
    vb = (w * wb * wb).sum((-1, -2)) - mb**2
    cov = (w * wa * wb).sum((-1, -2)) - ma * mb
    return ((2 * ma * mb + SSIM_C1) * (2 * cov + SSIM_C2)
            / ((ma**2 + mb**2 + SSIM_C1) * (va + vb + SSIM_C2)))


@pytest.mark.parametrize("shape", [(23, 40), (14, 1100)])
def test_ssim_equals_the_window_by_window_definition(shape):
    # (14, 1100): the long axis is filtered in blocks, the short one by one band matrix.
    a = noise_image(shape + (1,), 4)[..., 0].astype(np.float64)
    b = np.clip(a + np.random.default_rng(5).normal(0, 0.1, a.shape), 0, 1)
    assert ssim(a, b) == pytest.approx(windowed_ssim_map(a, b).mean(), rel=1e-9)


def test_ssim_falls_as_noise_grows():
    image = noise_image() * 0.5 + 0.25
    rng = np.random.default_rng(3)
    scores = [ssim(image, np.clip(image + rng.normal(0, s, image.shape), 0, 1))
              for s in (0.01, 0.05, 0.2)]
    assert 1 > scores[0] > scores[1] > scores[2]


def test_ssim_on_images_smaller_than_the_window():
    image = noise_image((5, 6, 3))
    assert ssim(image, image) == pytest.approx(1.0)
    assert ssim(image, 1 - image) < 0.5


def test_foreground_psnr_counts_only_masked_pixels():
    reference = np.zeros((20, 20, 3))
    candidate = reference.copy()
    candidate[:10] += 0.1  # error only in the top half
    mask = np.zeros((20, 20), bool)
    mask[:10] = True
    assert foreground_psnr(reference, candidate, mask) == pytest.approx(20.0)
    assert psnr(reference, candidate) == pytest.approx(20.0 + 10 * math.log10(2))
    assert math.isnan(foreground_psnr(reference, candidate, np.zeros((20, 20), bool)))


def test_foreground_mask_threshold_is_strict():
    alpha = np.array([[0.0, 0.05, 0.0500001, 1.0]])
    assert foreground_mask(alpha).tolist() == [[False, False, True, True]]


def test_mismatched_shapes_are_input_errors():
    with pytest.raises(InputError, match="shapes differ"):
        psnr(np.zeros((4, 4, 3)), np.zeros((4, 5, 3)))
    with pytest.raises(InputError, match="mask shape"):
        foreground_psnr(np.zeros((4, 4, 3)), np.zeros((4, 4, 3)), np.ones((3, 3), bool))
