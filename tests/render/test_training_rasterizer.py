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
