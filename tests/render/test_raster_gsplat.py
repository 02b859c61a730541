"""The gsplat CUDA path agrees with the torch reference (needs a GPU and gsplat)."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.render.rasterize_gsplat import gsplat_available
from csgs_codec.render.rasterizer import render
from tests.codec.helpers import random_scene
from tests.render.test_raster_common import look_at_camera


@pytest.mark.gpu
def test_gsplat_matches_torch_closely():
    if not gsplat_available():
        pytest.skip("gsplat is not installed")
    scene = random_scene(3000, sh_degree=3, seed=7)
    cam = look_at_camera(np.array([0.3, -0.8, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         160, 120)
    ref = render(scene, cam, backend="torch")
    gpu = render(scene, cam, backend="gsplat")
    assert gpu.backend == "gsplat"
    # gsplat cuts footprints at 3 sigma instead of the exact 1/255 contour: close, not equal.
    assert np.abs(gpu.image - ref.image).mean() < 5e-3
    assert np.abs(gpu.alpha - ref.alpha).max() < 5e-2


def _tensors(scene, device):
    from csgs_codec.render.rasterizer import scene_tensors

    return {name: t.to(device).requires_grad_(True)
            for name, t in scene_tensors(scene).items()}


@pytest.mark.gpu
def test_gsplat_training_path_matches_the_reference_and_its_gradients():
    """The differentiable gsplat path gives the reference's image, depth and features, and
    gradients pointing the same way for every input (footprints cut at 3 sigma: close, not
    equal)."""
    import torch

    from csgs_codec.render.rasterize_gsplat import rasterize_gaussians_gsplat
    from csgs_codec.render.rasterize_torch import rasterize_gaussians

    if not gsplat_available():
        pytest.skip("gsplat is not installed")
    scene = random_scene(2000, sh_degree=1, seed=3)
    cam = look_at_camera(np.array([0.2, -0.6, -3.2]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         96, 72)
    features = torch.as_tensor(np.random.default_rng(0).normal(size=(2000, 5)),
                               dtype=torch.float32)
    target = torch.rand(72, 96, 3, generator=torch.Generator().manual_seed(1))
    grads, outputs = {}, {}
    for name, device, fn in (("torch", "cpu", rasterize_gaussians),
                             ("gsplat", "cuda", rasterize_gaussians_gsplat)):
        t = _tensors(scene, device)
        out = fn(t["means"], t["log_scales"], t["quats"], t["opacity_logits"], cam, sh=t["sh"],
                 features=features.to(device), background=(0.2, 0.3, 0.4))
        loss = ((out.image - target.to(device)) ** 2).mean() + out.features.square().mean()
        loss.backward()
        outputs[name] = {k: v.detach().cpu() for k, v in out._asdict().items()}
        grads[name] = {k: v.grad.detach().cpu() for k, v in t.items()}
    ref, gpu = outputs["torch"], outputs["gsplat"]
    assert (gpu["image"] - ref["image"]).abs().mean() < 5e-3
    assert (gpu["alpha"] - ref["alpha"]).abs().mean() < 5e-3
    assert (gpu["features"] - ref["features"]).abs().mean() < 2e-2
    covered = (ref["alpha"] > 0.5) & (gpu["alpha"] > 0.5)
    assert (gpu["depth"][covered] - ref["depth"][covered]).abs().mean() < 2e-2
    for name, g_ref in grads["torch"].items():
        g_gpu = grads["gsplat"][name].flatten().double()
        g_ref = g_ref.flatten().double()
        cosine = float(g_gpu @ g_ref / (g_gpu.norm() * g_ref.norm()))
        assert cosine > 0.95, (name, cosine)


@pytest.mark.gpu
def test_gsplat_training_path_runs_on_the_inputs_device():
    import torch

    from csgs_codec.render.differentiable import rasterize_for_training

    if not gsplat_available():
        pytest.skip("gsplat is not installed")
    t = _tensors(random_scene(500, sh_degree=0, seed=5), "cuda")
    cam = look_at_camera(np.array([0.0, 0.0, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         40, 30)
    colors = torch.sigmoid(t["sh"][:, 0, :])
    out = rasterize_for_training(t["means"], t["log_scales"], t["quats"], t["opacity_logits"],
                                 cam, colors=colors, rasterizer="auto")
    assert out.image.is_cuda and out.image.shape == (30, 40, 3)
    out.image.sum().backward()
    assert torch.isfinite(t["means"].grad).all() and t["means"].grad.abs().sum() > 0


@pytest.mark.gpu
def test_gsplat_without_depth_gives_the_same_image_alpha_and_gradients():
    """Training's form (RGB only, gsplat compositing the background, opacities given as
    such) renders and differentiates like the form with depth."""
    import torch

    from csgs_codec.render.rasterize_gsplat import rasterize_gaussians_gsplat

    if not gsplat_available():
        pytest.skip("gsplat is not installed")
    scene = random_scene(1500, sh_degree=0, seed=9)
    cam = look_at_camera(np.array([0.1, -0.5, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         64, 48)
    target = torch.rand(48, 64, 3, generator=torch.Generator().manual_seed(2)).cuda()
    results = []
    for with_depth in (True, False):
        t = _tensors(scene, "cuda")
        colors = torch.sigmoid(t["sh"][:, 0, :])
        out = rasterize_gaussians_gsplat(t["means"], t["log_scales"], t["quats"], None, cam,
                                         opacities=torch.sigmoid(t["opacity_logits"]),
                                         colors=colors, background=(0.2, 0.3, 0.4),
                                         with_depth=with_depth)
        assert (out.depth is None) == (not with_depth)
        (((out.image - target) ** 2).mean() + out.alpha.mean()).backward()
        results.append((out.image.detach(), out.alpha.detach(),
                        {k: v.grad.detach() for k, v in t.items()}))
    (image, alpha, grads), (image2, alpha2, grads2) = results
    torch.testing.assert_close(image2, image, atol=1e-5, rtol=1e-4)
    torch.testing.assert_close(alpha2, alpha, atol=1e-5, rtol=1e-4)
    for name, grad in grads.items():
        scale = float(grad.abs().max()) + 1e-12
        torch.testing.assert_close(grads2[name] / scale, grad / scale, atol=1e-4, rtol=1e-3,
                                   msg=name)
