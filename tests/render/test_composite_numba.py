"""The numba training compositor gives the torch reference's images and gradients."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.rasterize_torch import rasterize_gaussians
from csgs_codec.render.rasterizer import scene_tensors
from tests.codec.helpers import random_scene
from tests.conftest import shared_path
from tests.render.test_raster_common import look_at_camera, orbit_view

pytestmark = pytest.mark.skipif(not numba_available(), reason="numba not installed")


def _render_with_gradients(tensors: dict, camera, compositor: str, features=None):
    """Maps and the gradients of a loss that weighs every output differently."""
    leaves = {k: v.detach().clone().requires_grad_() for k, v in tensors.items()}
    feats = None if features is None else features.detach().clone().requires_grad_()
    out = rasterize_gaussians(**leaves, camera=camera, features=feats,
                              background=(0.2, 0.3, 0.4), compositor=compositor)
    gen = torch.Generator().manual_seed(7)
    loss = (out.image * torch.rand(out.image.shape, generator=gen)).sum()
    loss = loss + 0.3 * (out.alpha * torch.rand(out.alpha.shape, generator=gen)).sum()
    loss = loss + 0.01 * (out.depth * out.alpha).sum()
    if feats is not None:
        loss = loss + (out.features * torch.rand(out.features.shape, generator=gen)).sum()
    loss.backward()
    grads = {k: v.grad for k, v in leaves.items()}
    if feats is not None:
        grads["features"] = feats.grad
    return out, grads


def _assert_same_as_reference(tensors, camera, features=None):
    ref, ref_grads = _render_with_gradients(tensors, camera, "torch", features)
    fast, fast_grads = _render_with_gradients(tensors, camera, "numba", features)
    assert float(ref.alpha.detach().max()) > 0.5, "the view must show something"
    for name in ("image", "alpha", "features"):
        if getattr(ref, name) is not None:
            torch.testing.assert_close(getattr(fast, name), getattr(ref, name), rtol=0,
                                       atol=2e-5)
    for name, grad in ref_grads.items():
        assert float(grad.abs().max()) > 0, f"{name}: the loss must reach it"
        relative = float((fast_grads[name] - grad).norm() / grad.norm())
        assert relative < 1e-4, f"{name}: gradient differs by {relative:.2e} (relative)"


@pytest.mark.parametrize("sh_degree", [0, 3])
def test_images_and_gradients_match_the_reference_on_random_scenes(sh_degree):
    scene = random_scene(1500, sh_degree=sh_degree, seed=sh_degree)
    cam = look_at_camera(np.array([0.3, -0.8, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         96, 72)
    feats = torch.randn(len(scene), 3, generator=torch.Generator().manual_seed(1))
    _assert_same_as_reference(scene_tensors(scene), cam, feats)


def test_opaque_stacks_stop_where_the_reference_stops():
    # Opaque, overlapping Gaussians: alphas hit the 0.99 clamp and transmittance reaches the
    # stop level, the two places where the rule is not smooth.
    scene = random_scene(800, sh_degree=1, seed=5)
    scene.opacity[:] = 8.0
    scene.scales[:] += 1.5
    cam = look_at_camera(np.array([0.0, 0.0, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         64, 48)
    ref = rasterize_gaussians(**scene_tensors(scene), camera=cam)
    assert float(ref.alpha.max()) > 0.9998, "some pixel must reach the stop level"
    _assert_same_as_reference(scene_tensors(scene), cam)


def test_a_real_scene_matches_the_reference():
    scene = read_ply(shared_path("scenes", "donut.ply"))
    cam = orbit_view(scene, np.array([0.0, 0.0, 1.0]), 120, 90)
    _assert_same_as_reference(scene_tensors(scene), cam)


def test_gradients_are_the_same_on_every_run():
    scene = random_scene(1200, sh_degree=1, seed=3)
    cam = look_at_camera(np.array([0.3, -0.8, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         80, 60)
    _, first = _render_with_gradients(scene_tensors(scene), cam, "numba")
    _, second = _render_with_gradients(scene_tensors(scene), cam, "numba")
    for name in first:
        assert torch.equal(first[name], second[name]), name


def test_a_view_of_nothing_gives_constant_maps_without_gradient():
    scene = random_scene(50, seed=2)
    cam = look_at_camera(np.array([0.0, 0.0, -3.0]), np.array([0.0, 0.0, -6.0]),
                         np.array([0.0, -1.0, 0.0]), 16, 12)
    out = rasterize_gaussians(**scene_tensors(scene), camera=cam, compositor="numba")
    assert torch.equal(out.alpha, torch.zeros(12, 16)) and not out.image.requires_grad


def test_float64_inputs_are_refused_by_the_numba_compositor_and_kept_by_auto():
    scene = random_scene(50, seed=2)
    cam = look_at_camera(np.array([0.0, 0.0, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         16, 12)
    tensors = scene_tensors(scene, dtype=torch.float64)
    with pytest.raises(InputError, match="float32"):
        rasterize_gaussians(**tensors, camera=cam, compositor="numba")
    auto = rasterize_gaussians(**tensors, camera=cam, compositor="auto")
    ref = rasterize_gaussians(**tensors, camera=cam, compositor="torch")
    assert torch.equal(auto.image, ref.image)
    with pytest.raises(InputError, match="compositor"):
        rasterize_gaussians(**tensors, camera=cam, compositor="gpu")
