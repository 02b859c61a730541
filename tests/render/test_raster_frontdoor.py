"""render(): output layout, backend choice and input checks (csgs_codec.render.rasterizer)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.rasterizer import render, resolve_backend
from tests.codec.helpers import random_scene
from tests.render.test_raster_common import look_at_camera

CAMERA = look_at_camera(np.array([0.0, -0.3, -3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0]),
                        20, 14)


def test_render_returns_float32_maps_of_the_camera_size():
    scene = random_scene(200, sh_degree=1, seed=4)
    out = render(scene, CAMERA, backend="torch", features=np.ones((200, 2), np.float32))
    assert out.image.shape == (14, 20, 3) and out.image.dtype == np.float32
    assert out.alpha.shape == (14, 20) and out.alpha.dtype == np.float32
    assert out.depth.shape == (14, 20) and out.depth.dtype == np.float32
    assert out.features.shape == (14, 20, 2) and out.features.dtype == np.float32
    # A constant feature of 1 renders as the accumulated alpha.
    np.testing.assert_allclose(out.features[..., 0], out.alpha, atol=1e-6)


def test_auto_backend_prefers_numba_on_a_cpu_machine():
    expected = "numba" if numba_available() else "torch"
    assert resolve_backend("auto") in (expected, "gsplat")


def test_unknown_backend_is_an_input_error():
    with pytest.raises(InputError, match="backend"):
        render(random_scene(5, sh_degree=0, seed=0), CAMERA, backend="opengl")


@pytest.mark.parametrize("change", [
    {"width": 0}, {"width": 100_000, "height": 100_000}, {"fx": 0.0}, {"cy": float("nan")},
    {"world_to_camera": np.full((4, 4), np.inf)}, {"world_to_camera": np.eye(3)},
])
def test_bad_cameras_are_input_errors(change):
    camera = dataclasses.replace(CAMERA, **change)
    with pytest.raises(InputError, match="camera"):
        render(random_scene(5, sh_degree=0, seed=0), camera)


def test_features_with_the_wrong_row_count_are_an_input_error():
    with pytest.raises(InputError, match="features"):
        render(random_scene(5, sh_degree=0, seed=0), CAMERA, features=np.zeros((4, 2), np.float32))


def test_bad_background_is_an_input_error():
    with pytest.raises(InputError, match="background"):
        render(random_scene(5, sh_degree=0, seed=0), CAMERA, background=(0.0, 1.0))


def test_non_finite_scene_values_are_an_input_error_naming_the_gaussian():
    scene = random_scene(5, sh_degree=0, seed=0)
    scene.scales[3, 1] = np.nan
    with pytest.raises(InputError, match="index 3"):
        render(scene, CAMERA)

