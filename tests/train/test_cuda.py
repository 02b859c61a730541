"""The loss terms and stage 2 give the CPU's results on a CUDA device."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.train.losses import (
    inter_mask_contrastive_loss,
    intra_mask_smoothing_loss,
    photometric_loss,
)
from csgs_codec.train.quantization import gaussian_rate_bits, quality_aware_weights
from csgs_codec.train.semantic_stage import prepare_semantic_views, train_semantic_features
from csgs_codec.train.synthetic import make_synthetic_dataset

pytestmark = pytest.mark.gpu


def test_losses_on_cuda_equal_the_cpu():
    generator = torch.Generator().manual_seed(0)
    image = torch.rand(20, 24, 3, generator=generator, dtype=torch.float64)
    target = torch.rand(20, 24, 3, generator=generator, dtype=torch.float64)
    features = torch.randn(20, 24, 6, generator=generator, dtype=torch.float64)
    mask = torch.randint(0, 4, (20, 24), generator=generator)
    for loss, args in ((photometric_loss, (image, target)),
                       (intra_mask_smoothing_loss, (features, mask)),
                       (inter_mask_contrastive_loss, (features, mask))):
        cpu = loss(*args).item()
        assert loss(*(a.cuda() for a in args)).item() == pytest.approx(cpu, rel=1e-9)
    values, mean, sigma = (torch.randn(100, generator=generator, dtype=torch.float64)
                           for _ in range(3))
    sigma = sigma.abs() + 0.5
    cpu = gaussian_rate_bits(values, mean, sigma, 1.0)
    gpu = gaussian_rate_bits(values.cuda(), mean.cuda(), sigma.cuda(), 1.0).cpu()
    torch.testing.assert_close(gpu, cpu)
    steps = torch.tensor([1.0, 2.0, 3.0, 5.0])
    torch.testing.assert_close(quality_aware_weights(steps.cuda()).cpu(),
                               quality_aware_weights(steps))


def test_semantic_stage_trains_on_cuda():
    dataset = make_synthetic_dataset(11, objects=3, gaussians_per_object=50, views=3,
                                     width=32, height=24)
    views = prepare_semantic_views(dataset.scene, dataset.views)
    result = train_semantic_features(views, len(dataset.scene), iterations=40, seed=4,
                                     device="cuda")
    assert np.all(np.isfinite(result.features))
    assert result.losses[-1] < 0.2 * result.losses[0]


@pytest.mark.parametrize("rasterizer", ["torch", "gsplat"])
def test_stage_one_trains_on_cuda(rasterizer):
    from csgs_codec.render.rasterize_gsplat import gsplat_available
    from csgs_codec.train.color_stage import initial_state, train_color_stage
    from tests.train.stage1_data import tiny_color_settings, tiny_dataset

    if rasterizer == "gsplat" and not gsplat_available():
        pytest.skip("gsplat is not installed")
    data = tiny_dataset()
    state = initial_state(data.views, data.scene.positions,
                          tiny_color_settings(device="cuda", rasterizer=rasterizer))
    train_color_stage(data.views, state)
    psnr = np.asarray(state.history["psnr"])
    assert np.isfinite(state.history["loss"]).all()
    assert psnr[-10:].mean() > psnr[:5].mean() + 8.0
    assert state.model.to_anchor_scene().positions.shape[1] == 3


def test_segment_on_cuda_finds_the_cpu_instances():
    from csgs_codec.train.segment import SegmentSettings, segment_scene

    dataset = make_synthetic_dataset(7, objects=4, gaussians_per_object=150, views=6,
                                     width=64, height=48)
    cpu = segment_scene(dataset.scene, dataset.views, SegmentSettings(iterations=80))
    gpu = segment_scene(dataset.scene, dataset.views,
                        SegmentSettings(iterations=80, device="cuda"))
    labels = dataset.scene.labels
    for result in (cpu, gpu):
        assert result.instances.count == 4
        for label in np.unique(labels):
            ids, counts = np.unique(result.instances.ids[labels == label], return_counts=True)
            assert counts.max() >= 0.95 * counts.sum(), label


def test_all_slot_spawn_through_gsplat_matches_the_kept_slots():
    """The form stage 1 takes on a GPU (every slot, hidden ones at opacity 0, rotations
    left to gsplat to normalise) renders and differentiates like the gathered form."""
    from csgs_codec.render.rasterize_gsplat import gsplat_available
    from csgs_codec.train.anchor_model import AnchorGrid, AnchorModel
    from tests.train.stage1_data import tiny_dataset

    if not gsplat_available():
        pytest.skip("gsplat is not installed")
    data = tiny_dataset()
    cells = np.unique(np.floor(data.scene.positions / 0.25).astype(np.int64), axis=0)
    model = AnchorModel(cells, AnchorGrid(np.zeros(3), 0.25), feat_dim=8, n_offsets=4,
                        seed=3, device="cuda")
    with torch.no_grad():
        model.features.normal_(0.0, 0.5)
        model.mask_logits.normal_(0.0, 6.0)
    results = []
    for all_slots in (False, True):
        model.zero_grad(set_to_none=True)
        out, _ = model.render(data.views[0].camera, rasterizer="gsplat", all_slots=all_slots)
        (out.image.square().sum() + out.alpha.sum()).backward()
        results.append((out.image.detach(), {n: p.grad.clone()
                                             for n, p in model.named_parameters()
                                             if p.grad is not None}))
    (kept_image, kept_grads), (all_image, all_grads) = results
    torch.testing.assert_close(all_image, kept_image, atol=1e-5, rtol=1e-4)
    for name, grad in kept_grads.items():
        scale = float(grad.abs().max()) + 1e-12
        torch.testing.assert_close(all_grads[name] / scale, grad / scale, atol=1e-4,
                                   rtol=1e-3, msg=name)
