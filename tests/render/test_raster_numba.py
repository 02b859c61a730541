"""The numba forward path matches the torch reference to 1e-4 per pixel."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import CsgsWarning
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.render import rasterizer
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.rasterizer import render
from tests.codec.helpers import random_scene
from tests.conftest import shared_path
from tests.render.test_raster_common import look_at_camera, orbit_view

needs_numba = pytest.mark.skipif(not numba_available(), reason="numba not installed")
TOLERANCE = 1e-4


def _assert_backends_agree(scene, camera, **kwargs):
    ref = render(scene, camera, backend="torch", **kwargs)
    fast = render(scene, camera, backend="numba", **kwargs)
    assert fast.backend == "numba" and ref.backend == "torch"
    assert ref.alpha.max() > 0.5, "the view must actually show something"
    np.testing.assert_allclose(fast.image, ref.image, rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(fast.alpha, ref.alpha, rtol=0, atol=TOLERANCE)
    # Accumulated depth (depth * alpha) is what both composite; compare it scaled to the view.
    scale = float(ref.depth.max())
    np.testing.assert_allclose(fast.depth * fast.alpha / scale, ref.depth * ref.alpha / scale,
                               rtol=0, atol=TOLERANCE)
    if ref.features is not None:
        np.testing.assert_allclose(fast.features, ref.features, rtol=0, atol=TOLERANCE)


@needs_numba
@pytest.mark.parametrize("sh_degree", [0, 3])
def test_numba_matches_torch_on_random_scenes(sh_degree):
    scene = random_scene(1500, sh_degree=sh_degree, seed=sh_degree)
    cam = look_at_camera(np.array([0.3, -0.8, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         96, 72)
    feats = np.random.default_rng(1).normal(size=(len(scene), 3)).astype(np.float32)
    _assert_backends_agree(scene, cam, features=feats, background=(0.1, 0.3, 0.2))


@needs_numba
def test_numba_matches_torch_with_the_camera_inside_the_scene():
    scene = random_scene(1500, sh_degree=1, seed=11, spread=2.0)
    cam = look_at_camera(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.2, 1.0]),
                         np.array([0.0, -1.0, 0.0]), 80, 60, fov_deg=90)
    _assert_backends_agree(scene, cam)


@needs_numba
def test_numba_matches_torch_on_a_real_scene_subset_donut():
    scene = read_ply(shared_path("scenes", "donut.ply"))
    scene = scene.subset(np.random.default_rng(0).permutation(len(scene))[:6000])
    _assert_backends_agree(scene, orbit_view(scene, [0, 0, 1], 120, 90, azimuth_deg=30))


@needs_numba
def test_numba_matches_torch_on_a_real_scene_subset_playbot_sh2():
    scene = read_ply(shared_path("scenes", "playbot.ply"))
    scene = scene.subset(np.random.default_rng(0).permutation(len(scene))[:8000])
    assert scene.sh_degree_in_use() == 2
    _assert_backends_agree(scene, orbit_view(scene, [0, -1, 0], 120, 90, azimuth_deg=200))


@needs_numba
def test_numba_result_does_not_depend_on_the_tile_size():
    from csgs_codec.render.rasterize_numba import rasterize_numba
    from csgs_codec.render.rasterize_torch import prepare_gaussians
    from csgs_codec.render.rasterizer import scene_tensors

    scene = random_scene(800, sh_degree=1, seed=21)
    cam = look_at_camera(np.array([0.3, -0.8, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         70, 50)
    t = scene_tensors(scene)
    prepared = prepare_gaussians(t["means"], t["log_scales"], t["quats"], t["opacity_logits"],
                                 cam, sh=t["sh"])
    small = rasterize_numba(prepared, cam, tile_size=4)
    large = rasterize_numba(prepared, cam, tile_size=32)
    assert small.alpha.max() > 0.5
    np.testing.assert_array_equal(small.image, large.image)


def test_numba_request_without_numba_falls_back_to_torch_with_a_warning(monkeypatch):
    monkeypatch.setattr(rasterizer, "numba_available", lambda: False)
    scene = random_scene(50, sh_degree=0, seed=2)
    cam = look_at_camera(np.array([0.0, 0.0, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                         16, 12)
    with pytest.warns(CsgsWarning, match="numba is not installed"):
        out = render(scene, cam, backend="numba")
    assert out.backend == "torch"
    assert rasterizer.resolve_backend("auto") == "torch"
