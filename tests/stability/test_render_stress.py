"""Stress scenes through the renderer: finite images from the numba and torch backends.

Rules: rendering a stress scene (as built, and as decoded at quality 1) gives finite image,
alpha and depth on both CPU backends, from the scene's own orbit view and from a fixed view
of a unit scene; the numba path agrees with the torch reference on them; framing a scene with
saturated opacity logits raises no floating-point warnings; a quaternion's length never changes
the render; long thin Gaussians project to the conics float64 gives (no cancellation in the
footprint's determinant); a scene of extent 1e-6 renders as its unit-size twin does; a camera
whose near plane is not finite and positive is refused.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import torch

from csgs_codec.attributes.attribute_forms import normalize_quaternions
from csgs_codec.errors import InputError
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.projection import project_gaussians
from csgs_codec.render.rasterizer import render, scene_tensors
from csgs_codec.scene.orbit import orbit_cameras
from tests.stability.round_trips import stress_round_trip
from tests.stability.stress_scenes import STRESS_SCENES, plain_scene

BACKENDS = [pytest.param("torch"),
            pytest.param("numba", marks=pytest.mark.skipif(not numba_available(),
                                                           reason="numba not installed"))]
WIDTH, HEIGHT = 40, 30


def _cameras(scene):
    """One orbit view of ``scene`` (none when it is empty) and one view of a unit scene."""
    fixed = orbit_cameras(plain_scene(), count=1, width=WIDTH, height=HEIGHT)
    if len(scene) == 0:
        return fixed
    return orbit_cameras(scene, count=1, width=WIDTH, height=HEIGHT) + fixed


@pytest.mark.parametrize("source", ["input", "decoded"])
@pytest.mark.parametrize("name", list(STRESS_SCENES))
@pytest.mark.parametrize("backend", BACKENDS)
def test_render_of_a_stress_scene_is_finite(backend, name, source):
    trip = stress_round_trip(name, 1)
    scene = trip.original if source == "input" else trip.decoded
    for camera in _cameras(scene):
        out = render(scene, camera, backend=backend)
        assert out.backend == backend
        for label, image in (("image", out.image), ("alpha", out.alpha), ("depth", out.depth)):
            assert np.all(np.isfinite(image)), f"{label} of {camera.name}"
        assert out.alpha.min() >= 0 and out.alpha.max() <= 1 + 1e-6


@pytest.mark.skipif(not numba_available(), reason="numba not installed")
@pytest.mark.parametrize("name", list(STRESS_SCENES))
def test_numba_matches_torch_on_a_stress_scene(name):
    scene = stress_round_trip(name, 1).original
    for camera in _cameras(scene):
        ref = render(scene, camera, backend="torch")
        fast = render(scene, camera, backend="numba")
        # Colors of +-65504 SH coefficients are huge: compare relative to the brightest pixel.
        scale = max(1.0, float(np.abs(ref.image).max()))
        np.testing.assert_allclose(fast.image / scale, ref.image / scale, rtol=0, atol=1e-4)
        np.testing.assert_allclose(fast.alpha, ref.alpha, rtol=0, atol=1e-4)
        depth_scale = max(1.0, float(ref.depth.max()))
        np.testing.assert_allclose(fast.depth * fast.alpha / depth_scale,
                                   ref.depth * ref.alpha / depth_scale, rtol=0, atol=1e-4)


@pytest.mark.parametrize("name", ["opacity_logits_1e4", "float16_range"])
def test_orbit_framing_of_saturated_opacities_raises_no_warning(name):
    scene = STRESS_SCENES[name]()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cameras = orbit_cameras(scene, count=2, width=WIDTH, height=HEIGHT)
    assert len(cameras) == 2


@pytest.mark.parametrize("name", ["unnormalised_zero_quaternions", "log_scales_-30_to_10"])
@pytest.mark.parametrize("backend", BACKENDS)
def test_quaternion_length_does_not_change_the_render(backend, name):
    scene = STRESS_SCENES[name]()
    unit = scene.subset(np.arange(len(scene)))
    unit.rotations = normalize_quaternions(scene.rotations)
    camera = orbit_cameras(scene, count=1, width=64, height=48)[0]
    a = render(scene, camera, backend=backend)
    b = render(unit, camera, backend=backend)
    assert a.alpha.max() > 0.5
    np.testing.assert_allclose(a.image, b.image, rtol=0, atol=1e-4)


def test_thin_huge_gaussians_project_as_in_float64():
    scene = STRESS_SCENES["log_scales_-30_to_10"]()
    camera = orbit_cameras(scene, count=1, width=192, height=144)[0]
    projected = {}
    for dtype in (torch.float32, torch.float64):
        t = scene_tensors(scene, dtype=dtype)
        projected[dtype] = project_gaussians(t["means"], t["log_scales"], t["quats"],
                                             t["opacity_logits"], camera)
    single, double = projected[torch.float32], projected[torch.float64]
    assert torch.equal(single.visible, double.visible)
    conics = double.conics[double.visible]
    error = (single.conics[double.visible].double() - conics).abs()
    assert float((error / conics.abs().amax(-1, keepdim=True)).max()) < 1e-4


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_micro_scene_renders_like_its_unit_size_twin(backend):
    tiny, unit = STRESS_SCENES["extent_1e-6"](), STRESS_SCENES["plain"]()
    a = render(tiny, orbit_cameras(tiny, count=1, width=WIDTH, height=HEIGHT)[0],
               backend=backend)
    b = render(unit, orbit_cameras(unit, count=1, width=WIDTH, height=HEIGHT)[0],
               backend=backend)
    assert b.alpha.max() > 0.5
    np.testing.assert_allclose(a.image, b.image, rtol=0, atol=1e-3)
    np.testing.assert_allclose(a.alpha, b.alpha, rtol=0, atol=1e-3)


@pytest.mark.parametrize("near_plane", [0.0, -1.0, float("nan"), float("inf")])
def test_a_camera_with_a_bad_near_plane_is_refused(near_plane):
    camera = orbit_cameras(plain_scene(), count=1, width=WIDTH, height=HEIGHT)[0]
    with pytest.raises(InputError) as err:
        render(plain_scene(), dataclasses.replace(camera, near_plane=near_plane))
    assert err.value.property == "camera"
