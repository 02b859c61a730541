"""Photometric and semantic loss terms, each on a case with a known answer."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.train.losses import (
    inter_mask_contrastive_loss,
    intra_mask_smoothing_loss,
    l1_loss,
    mask_means,
    photometric_loss,
    ssim,
)


def random_image(seed: int, shape=(24, 32, 3)) -> torch.Tensor:
    return torch.rand(shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)


def two_mask_features(offset: float, dim: int = 6):
    """Left half mask 0 with feature 0, right half mask 1 with feature ``offset`` * e_0."""
    mask = torch.zeros(8, 10, dtype=torch.int64)
    mask[:, 5:] = 1
    features = torch.zeros(8, 10, dim, dtype=torch.float64)
    features[:, 5:, 0] = offset
    return features, mask


def test_l1_of_known_difference():
    a = torch.zeros(2, 3)
    b = torch.tensor([[1.0, -2.0, 3.0], [0.0, 0.0, 0.0]])
    assert l1_loss(a, b).item() == pytest.approx(1.0)


def test_ssim_of_an_image_with_itself_is_one():
    image = random_image(0)
    assert ssim(image, image).item() == pytest.approx(1.0, abs=1e-12)
    small = random_image(1, (6, 7, 3))  # smaller than the window: one whole-image window
    assert ssim(small, small).item() == pytest.approx(1.0, abs=1e-12)


def test_ssim_gradient_moves_towards_the_target():
    target = random_image(4)
    rendered = (0.5 * target + 0.5 * random_image(5)).requires_grad_(True)
    before = ssim(rendered, target)
    before.backward()
    with torch.no_grad():
        after = ssim(rendered + 0.05 * rendered.grad / rendered.grad.abs().max(), target)
    assert after.item() > before.item()


def test_photometric_loss_is_zero_for_equal_images_and_weighted_otherwise():
    image = random_image(6)
    assert photometric_loss(image, image).item() == pytest.approx(0.0, abs=1e-12)
    other = random_image(7)
    expected = 0.8 * l1_loss(image, other) + 0.2 * (1 - ssim(image, other))
    assert photometric_loss(image, other).item() == pytest.approx(expected.item())


def test_smoothing_loss_is_zero_for_a_constant_feature_per_mask():
    features, mask = two_mask_features(2.5)
    assert intra_mask_smoothing_loss(features, mask).item() == 0.0


def test_smoothing_loss_is_the_mean_over_masks_of_the_squared_spread():
    # Mask 0: two pixels at 0 and 2 (mean 1, mean squared distance 1); mask 1: constant.
    features = torch.tensor([[[0.0], [2.0], [5.0], [5.0]]])
    mask = torch.tensor([[0, 0, 1, 1]])
    assert intra_mask_smoothing_loss(features, mask).item() == pytest.approx(0.5)


def test_smoothing_loss_ignores_the_ignore_id():
    features = torch.tensor([[[0.0], [2.0], [5.0], [7.0]]])
    mask = torch.tensor([[0, 0, 1, 1]])
    assert intra_mask_smoothing_loss(features, mask, ignore_id=0).item() == pytest.approx(1.0)


def test_contrastive_loss_is_zero_when_masks_are_beyond_the_margin():
    features, mask = two_mask_features(3.5)
    assert inter_mask_contrastive_loss(features, mask, margin=3.0).item() == 0.0


def test_contrastive_loss_of_close_masks_has_the_known_value():
    features, mask = two_mask_features(1.0)
    assert inter_mask_contrastive_loss(features, mask, margin=3.0).item() == pytest.approx(4.0)


def test_contrastive_gradient_pushes_the_mask_means_apart():
    features, mask = two_mask_features(0.5)
    features.requires_grad_(True)
    inter_mask_contrastive_loss(features, mask).backward()
    with torch.no_grad():
        stepped = features - 0.1 * features.grad
    means = mask_means(stepped, mask)
    assert torch.linalg.norm(means[1] - means[0]).item() > 0.5
    # Descending the loss separates two coincident masks too (the gradient exists at 0).
    coincident, _ = two_mask_features(0.0)
    coincident = coincident + 1e-3 * torch.randn(coincident.shape,
                                                 generator=torch.Generator().manual_seed(0),
                                                 dtype=torch.float64)
    for _ in range(50):
        coincident.requires_grad_(True)
        inter_mask_contrastive_loss(coincident, mask).backward()
        coincident = (coincident - 50.0 * coincident.grad).detach()
    assert inter_mask_contrastive_loss(coincident, mask).item() == 0.0


def test_contrastive_loss_averages_over_mask_pairs():
    # Three masks at 0, 1 and 10 on a line: pairs (0,1) cost (3-1)^2, the others nothing.
    features = torch.tensor([[[0.0], [1.0], [10.0]]])
    mask = torch.tensor([[4, 7, 9]])
    assert inter_mask_contrastive_loss(features, mask, margin=3.0).item() == pytest.approx(
        4.0 / 3.0)


def test_contrastive_loss_of_a_single_mask_is_zero_with_a_gradient():
    features = torch.ones(3, 3, 2, requires_grad=True)
    loss = inter_mask_contrastive_loss(features, torch.zeros(3, 3, dtype=torch.int32))
    loss.backward()
    assert loss.item() == 0.0 and features.grad is not None


def test_float_masks_and_mismatched_shapes_are_rejected():
    features = torch.zeros(4, 4, 2)
    with pytest.raises(InputError, match="integer"):
        intra_mask_smoothing_loss(features, torch.zeros(4, 4))
    with pytest.raises(InputError, match="mask"):
        inter_mask_contrastive_loss(features, torch.zeros(4, 5, dtype=torch.int64))
    with pytest.raises(InputError, match="shapes differ"):
        ssim(torch.zeros(12, 12), torch.zeros(12, 13))


def test_losses_accept_numpy_converted_masks():
    mask = torch.from_numpy(np.array([[0, 1], [0, 1]], np.int32))
    features = torch.tensor([[[0.0], [7.0]], [[0.0], [7.0]]])
    assert inter_mask_contrastive_loss(features, mask).item() == 0.0


@pytest.mark.parametrize("shape", [(384, 512, 3), (23, 40, 1), (11, 30, 3)])
def test_ssim_numba_kernels_give_the_reference_value_and_gradient(shape):
    pytest.importorskip("numba")
    gen = torch.Generator().manual_seed(sum(shape))
    target = torch.rand(shape, generator=gen)
    image = (target + 0.1 * torch.randn(shape, generator=gen)).clamp(0, 1)
    results = {}
    for kernel in ("torch", "auto"):
        rendered = image.clone().requires_grad_()
        value = ssim(rendered, target, kernel=kernel)
        value.backward()
        results[kernel] = (float(value), rendered.grad)
    (ref_value, ref_grad), (value, grad) = results["torch"], results["auto"]
    assert value == pytest.approx(ref_value, abs=1e-6)
    assert float((grad - ref_grad).norm() / ref_grad.norm()) < 1e-5


def test_ssim_score_pass_sums_each_row_in_order():
    """The score pass forms a row's scores, then sums them: the same bits as the loop with
    the running sum in it (the kernel as it was, parallel over rows like it)."""
    numba = pytest.importorskip("numba")
    from csgs_codec.metrics import ssim_kernels
    from csgs_codec.metrics.ssim import SSIM_C1, SSIM_C2

    @numba.njit(cache=False, parallel=True)
    def plain(stats, c1, c2, slopes):
        _, channels, out_h, out_w = stats.shape
        rows = np.zeros(channels * out_h, np.float64)
        for job in numba.prange(channels * out_h):
            c, i = job // out_h, job % out_h
            total = 0.0
            for j in range(out_w):
                mu_a, mu_b = stats[0, c, i, j], stats[1, c, i, j]
                var_a = stats[2, c, i, j] - mu_a * mu_a
                var_b = stats[3, c, i, j] - mu_b * mu_b
                cov = stats[4, c, i, j] - mu_a * mu_b
                num1 = 2 * mu_a * mu_b + c1
                num2 = 2 * cov + c2
                den1 = mu_a * mu_a + mu_b * mu_b + c1
                den2 = var_a + var_b + c2
                den = den1 * den2
                score = num1 * num2 / den
                total += score
                slopes[0, c, i, j] = (2 * mu_b * (num2 - num1) / den
                                      - score * 2 * mu_a * (1 / den1 - 1 / den2))
                slopes[1, c, i, j] = -score / den2
                slopes[2, c, i, j] = 2 * num1 / den
            rows[job] = total
        return rows.sum()

    rng = np.random.default_rng(4)
    a = rng.random((3, 40, 57), dtype=np.float32)
    b = np.clip(a + 0.2 * rng.standard_normal(a.shape), 0, 1).astype(np.float32)
    taps = np.exp(-0.5 * ((np.arange(11) - 5) / 1.5) ** 2)
    stats = ssim_kernels.window_statistics(a, b, (taps / taps.sum()).astype(np.float32))
    slopes = [np.empty((3,) + stats.shape[1:], np.float32) for _ in range(2)]
    fast = ssim_kernels.score_and_slopes(stats, SSIM_C1, SSIM_C2, slopes[0])
    assert fast == plain(stats, SSIM_C1, SSIM_C2, slopes[1])
    np.testing.assert_array_equal(slopes[0], slopes[1])


@pytest.mark.parametrize("shape", [(75, 90, 3), (11, 11, 1)])
def test_ssim_numba_kernels_give_the_same_bits_on_one_and_two_threads(shape):
    numba = pytest.importorskip("numba")
    gen = torch.Generator().manual_seed(7)
    target = torch.rand(shape, generator=gen)
    image = (target + 0.1 * torch.randn(shape, generator=gen)).clamp(0, 1)
    results = []
    previous = numba.get_num_threads()
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            rendered = image.clone().requires_grad_()
            value = ssim(rendered, target, kernel="auto")
            assert type(value.grad_fn).__name__ == "_NumbaSSIMBackward"
            value.backward()
            results.append((value.item(), rendered.grad.numpy().tobytes()))
    finally:
        numba.set_num_threads(previous)
    assert results[0] == results[1]


@pytest.mark.parametrize("shape", [(96, 128, 3), (23, 40, 1), (11, 30, 3)])
def test_ssim_written_out_gradient_gives_the_reference_value_and_gradient(shape, monkeypatch):
    import csgs_codec.metrics.ssim as ssim_module

    monkeypatch.setattr(ssim_module, "_numba_usable", lambda *args: False)  # as on a GPU
    gen = torch.Generator().manual_seed(sum(shape))
    target = torch.rand(shape, generator=gen, dtype=torch.float64)
    image = (target + 0.1 * torch.randn(shape, generator=gen, dtype=torch.float64)).clamp(0, 1)
    results = {}
    for kernel in ("torch", "auto"):
        rendered = image.clone().requires_grad_()
        value = ssim(rendered, target, kernel=kernel)
        assert (type(value.grad_fn).__name__ == "_AnalyticSSIMBackward") == (kernel == "auto")
        value.backward()
        results[kernel] = (float(value), rendered.grad)
    (ref_value, ref_grad), (value, grad) = results["torch"], results["auto"]
    assert value == pytest.approx(ref_value, abs=1e-12)
    assert float((grad - ref_grad).norm() / ref_grad.norm()) < 1e-10


def test_ssim_auto_kernel_leaves_a_target_that_needs_gradient_to_torch():
    gen = torch.Generator().manual_seed(2)
    a = torch.rand(20, 24, 3, generator=gen, requires_grad=True)
    b = torch.rand(20, 24, 3, generator=gen, requires_grad=True)
    ssim(a, b, kernel="auto").backward()
    assert a.grad is not None and b.grad is not None and float(b.grad.abs().max()) > 0
    with pytest.raises(InputError, match="kernel"):
        ssim(a, b, kernel="cuda")
