"""Jacobian sensitivities: the random-probe estimate of each coded value's weight in the
rendered squared error, checked against exact quantities."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.attributes.attribute_forms import quaternion_to_smallest_three
from csgs_codec.errors import InputError
from csgs_codec.render.jacobian_sensitivity import jacobian_sensitivity
from csgs_codec.render.projection import quaternions_from_smallest_three
from csgs_codec.render.rasterize_torch import rasterize_gaussians
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.orbit import look_at
from tests.render.synthetic import blob_scene

SH_C0 = 0.28209479177387814


def _camera(position, size=(48, 36)) -> Camera:
    width, height = size
    return Camera(width, height, 45.0, 45.0, width / 2, height / 2,
                  look_at(np.asarray(position, float), np.zeros(3), np.array([0.0, -1.0, 0.0])))


def _render(scene, camera, log_scales=None) -> np.ndarray:
    axis, rest = quaternion_to_smallest_three(scene.rotations)
    quats = quaternions_from_smallest_three(torch.as_tensor(axis.astype(np.int64)),
                                            torch.as_tensor(rest))
    sh = np.concatenate([scene.sh_dc[:, None, :], scene.sh_rest], axis=1)
    scales = scene.scales if log_scales is None else log_scales
    with torch.no_grad():
        image = rasterize_gaussians(torch.as_tensor(scene.positions, dtype=torch.float64),
                                    torch.as_tensor(scales, dtype=torch.float64),
                                    quats.double(), torch.as_tensor(scene.opacity).double(),
                                    camera, sh=torch.as_tensor(sh).double()).image
    return image.numpy()


def test_dc_sensitivity_is_c0_squared_times_the_blend_weight_sum():
    """color = 0.5 + C0 dc, so J2 of a DC coefficient is C0^2 sum (alpha T)^2 per channel."""
    pytest.importorskip("numba")
    from csgs_codec.render.sensitivity import blend_sensitivity

    scene = blob_scene(60, seed=5)
    cameras = [_camera((0.0, 0.0, -4.0)), _camera((3.0, 0.5, -2.5))]
    estimate = jacobian_sensitivity(scene, cameras, probes=48, seed=1)
    exact = SH_C0 ** 2 * blend_sensitivity(scene, cameras).weight_sq
    seen = exact > 1e-3 * exact.max()
    ratio = estimate.values["dc"].mean(axis=1)[seen] / exact[seen]
    assert seen.sum() >= 20
    assert np.median(ratio) == pytest.approx(1.0, abs=0.1)
    assert np.corrcoef(np.log(estimate.values["dc"].mean(axis=1)[seen]),
                       np.log(exact[seen]))[0, 1] > 0.95
    assert estimate.views == 2 and estimate.probes == 48


def test_scale_sensitivity_matches_finite_differences():
    """J2 of a log-scale is the summed squared image derivative, here by central
    differences on the largest contributor."""
    scene = blob_scene(30, seed=2)
    camera = _camera((0.0, 0.0, -4.0))
    estimate = jacobian_sensitivity(scene, [camera], probes=400, seed=3).values["scale"]
    gaussian, axis = np.unravel_index(np.argmax(estimate), estimate.shape)
    eps = 1e-4
    up, down = scene.scales.astype(np.float64), scene.scales.astype(np.float64)
    up[gaussian, axis] += eps
    down[gaussian, axis] -= eps
    derivative = (_render(scene, camera, up) - _render(scene, camera, down)) / (2 * eps)
    exact = float((derivative ** 2).sum())
    assert exact > 0
    assert estimate[gaussian, axis] == pytest.approx(exact, rel=0.25)


def test_groups_shapes_and_unseen_gaussians():
    """Every coded group, (N, C) each, non-negative; a view facing away sees nothing."""
    scene = blob_scene(20, seed=4)
    values = jacobian_sensitivity(scene, [_camera((0.0, 0.0, -4.0))]).values
    n, bands = len(scene), scene.sh_rest.shape[1]
    expected = {"position": (n, 3), "dc": (n, 3), "opacity": (n, 1), "scale": (n, 3),
                "rotation": (n, 3)}
    for band in range(1, 4):
        if bands >= band * (band + 2):
            expected[f"band{band}"] = (n, 3 * (2 * band + 1))
    assert {name: v.shape for name, v in values.items()} == expected
    assert all(np.all(v >= 0) for v in values.values())
    assert values["position"].sum() > 0
    away = Camera(48, 36, 45.0, 45.0, 24, 18,
                  look_at(np.array([0.0, 0.0, -4.0]), np.array([0.0, 0.0, -8.0]),
                          np.array([0.0, -1.0, 0.0])))
    unseen = jacobian_sensitivity(scene, [away]).values
    assert all(np.all(v == 0) for v in unseen.values())


def test_bad_arguments_are_refused():
    scene = blob_scene(5, seed=1)
    with pytest.raises(InputError):
        jacobian_sensitivity(scene, [])
    with pytest.raises(InputError):
        jacobian_sensitivity(scene, [_camera((0.0, 0.0, -4.0))], probes=0)
