"""The differentiable reference rasterizer (csgs_codec.render.rasterize_torch)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.render import composite_torch
from csgs_codec.render.rasterize_torch import rasterize_gaussians
from csgs_codec.render.rasterizer import scene_tensors
from tests.codec.helpers import random_scene
from tests.render.test_raster_common import camera_at_origin, look_at_camera


def _tiny_inputs(dtype=torch.float64):
    """Three overlapping Gaussians that cover a 9x7 image with alpha well inside (1/255, 0.99)."""
    means = torch.tensor([[0.02, -0.01, 2.0], [-0.03, 0.02, 2.4], [0.01, 0.03, 3.0]],
                         dtype=dtype)
    log_scales = torch.log(torch.tensor([[0.20, 0.15, 0.1], [0.18, 0.25, 0.12],
                                         [0.3, 0.2, 0.25]], dtype=dtype))
    quats = torch.tensor([[1.0, 0.1, -0.2, 0.05], [0.9, -0.3, 0.1, 0.2],
                          [0.7, 0.2, 0.2, -0.4]], dtype=dtype)
    logits = torch.tensor([0.3, -0.2, 0.8], dtype=dtype)
    gen = torch.Generator().manual_seed(0)
    sh = 0.3 * torch.randn(3, 4, 3, generator=gen, dtype=dtype)
    sh[:, 0] += 1.0
    feats = torch.randn(3, 2, generator=gen, dtype=dtype)
    return means, log_scales, quats, logits, sh, feats


def _gradcheck_all_inputs(fast_mode: bool) -> bool:
    cam = camera_at_origin(width=9, height=7, focal=20.0)
    inputs = tuple(t.requires_grad_() for t in _tiny_inputs())

    def run(means, log_scales, quats, logits, sh, feats):
        out = rasterize_gaussians(means, log_scales, quats, logits, cam, sh=sh,
                                  features=feats, background=(0.1, 0.2, 0.3))
        return out.image, out.alpha, out.depth, out.features

    return torch.autograd.gradcheck(run, inputs, eps=1e-6, atol=1e-6, rtol=1e-4,
                                    fast_mode=fast_mode)


def test_gradients_pass_gradcheck_in_float64():
    assert _gradcheck_all_inputs(fast_mode=True)


@pytest.mark.slow
def test_gradients_pass_full_gradcheck_in_float64():
    assert _gradcheck_all_inputs(fast_mode=False)


def test_gradients_flow_through_colors_given_directly():
    cam = camera_at_origin(width=9, height=7, focal=20.0)
    means, log_scales, quats, logits, _, _ = _tiny_inputs()
    colors = torch.tensor([[0.9, 0.2, 0.1], [0.1, 0.8, 0.3], [0.2, 0.3, 0.7]],
                          dtype=torch.float64, requires_grad=True)

    def run(colors):
        return rasterize_gaussians(means, log_scales, quats, logits, cam, colors=colors).image

    assert torch.autograd.gradcheck(run, (colors,), eps=1e-6, atol=1e-6)


def test_checkpointing_changes_neither_image_nor_gradients(monkeypatch):
    scene = random_scene(300, sh_degree=1, seed=5)
    cam = look_at_camera(np.array([0.0, -0.5, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         48, 40)
    results = []
    for checkpointed in (False, True):
        monkeypatch.setitem(composite_torch.composite.__kwdefaults__, "checkpointed",
                            checkpointed)
        t = {k: v.clone().requires_grad_() for k, v in scene_tensors(scene).items()}
        out = rasterize_gaussians(**t, camera=cam)
        loss = (out.image ** 2).sum() + out.alpha.sum() + out.depth.sum()
        results.append((loss.detach(), torch.autograd.grad(loss, list(t.values()))))
    (loss_a, grads_a), (loss_b, grads_b) = results
    assert torch.equal(loss_a, loss_b)
    assert all(g.abs().sum() > 0 for g in grads_a)
    for a, b in zip(grads_a, grads_b):
        assert torch.allclose(a, b, atol=1e-6)


def test_row_bands_do_not_change_the_image(monkeypatch):
    scene = random_scene(400, sh_degree=2, seed=9)
    cam = look_at_camera(np.array([0.2, -0.4, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         64, 48)
    t = scene_tensors(scene)
    with torch.no_grad():
        whole = rasterize_gaussians(**t, camera=cam)
        monkeypatch.setitem(composite_torch.composite.__kwdefaults__, "pair_budget", 500)
        banded = rasterize_gaussians(**t, camera=cam)
    assert torch.equal(whole.image, banded.image)
    assert torch.equal(whole.alpha, banded.alpha)


def test_depth_chunks_do_not_change_the_image(monkeypatch):
    scene = random_scene(600, sh_degree=1, seed=12)
    cam = look_at_camera(np.array([0.1, -0.3, -2.5]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         64, 48)
    t = scene_tensors(scene)
    with torch.no_grad():
        whole = rasterize_gaussians(**t, camera=cam)
        monkeypatch.setattr(composite_torch, "CHUNK_BUDGET", 200)
        chunked = rasterize_gaussians(**t, camera=cam)
    assert whole.alpha.max() > 0.9
    assert torch.allclose(whole.image, chunked.image, atol=1e-6)
    assert torch.allclose(whole.alpha, chunked.alpha, atol=1e-6)


def test_an_empty_scene_renders_the_background():
    cam = camera_at_origin(width=5, height=4)
    z = torch.zeros(0, 3)
    out = rasterize_gaussians(z, z, torch.zeros(0, 4), torch.zeros(0), cam,
                              colors=torch.zeros(0, 3), background=(0.5, 0.25, 1.0))
    assert torch.equal(out.image, torch.tensor([0.5, 0.25, 1.0]).expand(4, 5, 3))
    assert not out.alpha.any()


def test_sh_and_colors_together_are_rejected():
    means, log_scales, quats, logits, sh, _ = _tiny_inputs()
    with pytest.raises(InputError):
        rasterize_gaussians(means, log_scales, quats, logits, camera_at_origin(), sh=sh,
                            colors=sh[:, 0])


def test_mismatched_shapes_are_rejected_with_the_property_named():
    means, log_scales, quats, logits, sh, _ = _tiny_inputs()
    with pytest.raises(InputError, match="quats"):
        rasterize_gaussians(means, log_scales, quats[:, :3], logits, camera_at_origin(), sh=sh)
    with pytest.raises(InputError, match="features"):
        rasterize_gaussians(means, log_scales, quats, logits, camera_at_origin(), sh=sh,
                            features=torch.zeros(2, 1, dtype=torch.float64))
