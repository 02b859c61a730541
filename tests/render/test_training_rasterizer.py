"""Which differentiable rasterizer training takes, on machines without a GPU."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.render.differentiable import (
    rasterize_for_training,
    resolve_training_rasterizer,
)
from csgs_codec.render.rasterize_gsplat import rasterize_gaussians_gsplat
from csgs_codec.render.rasterize_torch import rasterize_gaussians
from csgs_codec.render.rasterizer import scene_tensors
from tests.codec.helpers import random_scene
from tests.render.test_raster_common import look_at_camera


def test_cpu_tensors_train_through_the_reference():
    assert resolve_training_rasterizer("auto", "cpu") == "torch"
    assert resolve_training_rasterizer("torch", "cpu") == "torch"
    with pytest.raises(UnsupportedError, match="cuda"):
        resolve_training_rasterizer("gsplat", "cpu")
    with pytest.raises(InputError, match="rasterizer"):
        resolve_training_rasterizer("optix", "cpu")


def test_gsplat_path_refuses_cpu_tensors():
    t = scene_tensors(random_scene(10, sh_degree=0))
    cam = look_at_camera(np.array([0.0, 0.0, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         8, 6)
    with pytest.raises(UnsupportedError):
        rasterize_gaussians_gsplat(t["means"], t["log_scales"], t["quats"],
                                   t["opacity_logits"], cam, sh=t["sh"])


def test_auto_on_the_cpu_renders_what_the_reference_renders():
    t = scene_tensors(random_scene(300, sh_degree=0, seed=2))
    cam = look_at_camera(np.array([0.0, 0.0, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         24, 18)
    colors = torch.sigmoid(t["sh"][:, 0, :])
    args = (t["means"], t["log_scales"], t["quats"], t["opacity_logits"], cam)
    auto = rasterize_for_training(*args, colors=colors, background=(0.1, 0.2, 0.3))
    ref = rasterize_gaussians(*args, colors=colors, background=(0.1, 0.2, 0.3))
    torch.testing.assert_close(auto.image, ref.image, rtol=1e-5, atol=1e-5)
    assert float(auto.alpha.max()) > 0.1


@pytest.mark.parametrize("compositor", ["torch", "numba"])
def test_skipping_the_depth_map_changes_no_image_alpha_or_gradient_bit(compositor):
    """``with_depth=False`` (what training asks for) composites one value fewer per
    Gaussian; the image, alpha and every gradient of a loss on them are the same bits."""
    if compositor == "numba":
        pytest.importorskip("numba")
    t = scene_tensors(random_scene(400, sh_degree=0, seed=5))
    cam = look_at_camera(np.array([0.2, -0.4, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         40, 30)
    results = []
    for with_depth in (True, False):
        leaves = {k: v.detach().clone().requires_grad_() for k, v in t.items() if k != "sh"}
        colors = torch.sigmoid(t["sh"][:, 0, :]).detach().requires_grad_()
        out = rasterize_gaussians(leaves["means"], leaves["log_scales"], leaves["quats"],
                                  leaves["opacity_logits"], cam, colors=colors,
                                  background=(0.1, 0.2, 0.3), compositor=compositor,
                                  with_depth=with_depth)
        assert (out.depth is None) == (not with_depth)
        weights = torch.rand(out.image.shape, generator=torch.Generator().manual_seed(3))
        ((out.image * weights).sum() + 0.5 * out.alpha.square().sum()).backward()
        grads = [leaves[k].grad for k in ("means", "log_scales", "quats", "opacity_logits")]
        results.append([out.image.detach(), out.alpha.detach(), colors.grad, *grads])
    assert float(results[0][1].max()) > 0.5, "the view must show something"
    for with_depth, without in zip(*results):
        assert torch.equal(with_depth, without)
