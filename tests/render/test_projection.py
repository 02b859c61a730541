"""Covariance, EWA projection and culling (csgs_codec.render.projection)."""

from __future__ import annotations

import math

import numpy as np
import torch

from csgs_codec.render.projection import (
    ALPHA_THRESHOLD,
    LOW_PASS_VARIANCE,
    covariance_3d,
    project_gaussians,
    quaternion_to_rotation,
)
from tests.render.test_raster_common import camera_at_origin


def _project(positions, log_scale=-3.0, opacity_logit=2.0, camera=None, **kwargs):
    pos = torch.tensor(positions, dtype=torch.float64).reshape(-1, 3)
    n = pos.shape[0]
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=torch.float64).repeat(n, 1)
    return project_gaussians(pos, torch.full((n, 3), log_scale, dtype=torch.float64), quats,
                             torch.full((n,), opacity_logit, dtype=torch.float64),
                             camera or camera_at_origin(), **kwargs)


def test_quaternions_are_normalised_before_use():
    q = torch.tensor([[3.0, 1.0, -2.0, 0.5]], dtype=torch.float64)
    rot = quaternion_to_rotation(q)[0]
    assert torch.allclose(rot @ rot.T, torch.eye(3, dtype=torch.float64), atol=1e-12)
    assert math.isclose(float(torch.linalg.det(rot)), 1.0, abs_tol=1e-12)


def test_quaternion_w_x_y_z_order_rotates_x_onto_y_about_z():
    half = math.pi / 4
    q = torch.tensor([[math.cos(half), 0.0, 0.0, math.sin(half)]], dtype=torch.float64) * 7
    rot = quaternion_to_rotation(q)[0]
    x_axis = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
    assert torch.allclose(rot @ x_axis, torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64),
                          atol=1e-12)


def test_covariance_is_rotated_squared_scales():
    log_scales = torch.log(torch.tensor([[0.1, 0.2, 0.3]], dtype=torch.float64))
    q = torch.tensor([[0.9, 0.1, -0.3, 0.2]], dtype=torch.float64)
    rot = quaternion_to_rotation(q)[0]
    expected = rot @ torch.diag(torch.tensor([0.01, 0.04, 0.09], dtype=torch.float64)) @ rot.T
    assert torch.allclose(covariance_3d(log_scales, q)[0], expected, atol=1e-14)


def test_isotropic_gaussian_facing_camera_projects_to_scaled_circle_plus_low_pass():
    sigma, z, focal = 0.05, 2.0, 40.0
    p = _project([0.0, 0.0, z], log_scale=math.log(sigma))
    cam = camera_at_origin()
    variance = (focal * sigma / z) ** 2 + LOW_PASS_VARIANCE
    assert torch.allclose(p.means2d[0], torch.tensor([cam.cx, cam.cy], dtype=torch.float64))
    assert torch.allclose(p.conics[0], torch.tensor([1 / variance, 0.0, 1 / variance],
                                                    dtype=torch.float64))
    assert float(p.depths[0]) == z
    assert bool(p.visible[0])


def test_centre_projects_with_pinhole_intrinsics():
    cam = camera_at_origin(width=200, height=100, focal=80.0)
    p = _project([0.3, -0.2, 4.0], camera=cam)
    expected = torch.tensor([80 * 0.3 / 4 + cam.cx, 80 * -0.2 / 4 + cam.cy], dtype=torch.float64)
    assert torch.allclose(p.means2d[0], expected)


def test_gaussians_at_or_behind_the_near_plane_are_culled():
    p = _project([[0.0, 0.0, 0.005], [0.0, 0.0, -1.0], [0.0, 0.0, 0.02]], near_plane=0.01)
    assert p.visible.tolist() == [False, False, True]
    assert torch.isfinite(p.means2d).all() and torch.isfinite(p.conics).all()


def test_gaussians_outside_the_frustum_are_culled():
    p = _project([[50.0, 0.0, 1.0], [0.0, -50.0, 1.0], [0.1, 0.1, 1.0]])
    assert p.visible.tolist() == [False, False, True]


def test_gaussians_too_transparent_to_reach_the_alpha_threshold_are_culled():
    logit = math.log(0.003 / 0.997)
    assert not bool(_project([0.0, 0.0, 2.0], opacity_logit=logit).visible[0])


def test_footprint_box_contains_every_pixel_with_alpha_above_threshold():
    rng = np.random.default_rng(3)
    n = 200
    pos = torch.tensor(rng.uniform([-0.5, -0.5, 1.5], [0.5, 0.5, 3.0], (n, 3)))
    quats = torch.tensor(rng.normal(size=(n, 4)))
    log_scales = torch.tensor(rng.normal(-3.0, 0.8, (n, 3)))
    logits = torch.tensor(rng.normal(0, 2, n))
    p = project_gaussians(pos, log_scales, quats, logits, camera_at_origin())
    a, b, c = p.conics.unbind(-1)
    det = a * c - b * b
    var_x, var_y = c / det, a / det
    # On the box's vertical side dx = extent_x the largest alpha over all dy is
    # opacity * exp(-0.5 extent_x^2 / var_x); likewise for the horizontal side.
    peak_x = p.opacities * torch.exp(-0.5 * p.extents[:, 0] ** 2 / var_x)
    peak_y = p.opacities * torch.exp(-0.5 * p.extents[:, 1] ** 2 / var_y)
    seen = p.opacities > ALPHA_THRESHOLD
    assert bool((peak_x[seen] < ALPHA_THRESHOLD).all())
    assert bool((peak_y[seen] < ALPHA_THRESHOLD).all())
    # ... and the box is not loose: slightly inside it alpha still reaches the threshold.
    inner = p.opacities * torch.exp(-0.5 * (0.99 * p.extents[:, 0] - 1e-3) ** 2 / var_x)
    assert bool((inner[seen] >= ALPHA_THRESHOLD).all())
