"""Render sensitivities: the blending-weight sums the view pruning ranks Gaussians by."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.render.rasterizer import render
from csgs_codec.render.sensitivity import blend_sensitivity
from csgs_codec.render.view_distribution import (
    DEFAULT_DIRECTIONS,
    DEFAULT_DISTANCES,
    camera_distribution,
    default_distribution,
    sphere_directions,
)
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.orbit import look_at
from tests.render.synthetic import blob_scene, scene_from

pytest.importorskip("numba")


def _camera(position, target=(0.0, 0.0, 0.0), size=(64, 48)) -> Camera:
    width, height = size
    return Camera(width, height, 60.0, 60.0, width / 2, height / 2,
                  look_at(np.asarray(position, float), np.asarray(target, float),
                          np.array([0.0, -1.0, 0.0])))


def test_weights_of_a_view_sum_to_its_rendered_alpha():
    """Sum over Gaussians and pixels of w = alpha * T is the image's accumulated opacity."""
    scene = blob_scene(200, seed=3)
    camera = _camera((0.0, 0.0, -4.0))
    sens = blend_sensitivity(scene, [camera])
    alpha = render(scene, camera, backend="numba").alpha
    assert sens.weight_sum.sum() == pytest.approx(float(alpha.sum()), rel=1e-4)
    assert np.all(sens.weight_sq <= sens.weight_sum + 1e-12)


def test_a_gaussian_hidden_behind_opaque_ones_weighs_nothing():
    """Three near-opaque layers in front end compositing (T < 1e-4) before the fourth."""
    front = scene_from([[0.0, 0.0, z] for z in (0.0, 0.05, 0.1)], log_scale=-0.5,
                       opacity_logit=12.0)
    rest = scene_from([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0]], log_scale=-3.0, opacity_logit=4.0)
    scene = front.subset(np.arange(3))
    for name in ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations"):
        setattr(scene, name, np.concatenate([getattr(front, name), getattr(rest, name)]))
    sens = blend_sensitivity(scene, [_camera((0.0, 0.0, -4.0), size=(96, 72))])
    assert np.all(sens.weight_sq[:3] > 0)
    assert sens.weight_sq[3] == 0.0 and sens.unseen[3]
    assert sens.weight_sq[4] > 0


def test_weights_add_up_over_views():
    scene = blob_scene(150, seed=1)
    a, b = _camera((0.0, 0.0, -4.0)), _camera((4.0, 0.0, 0.0))
    both = blend_sensitivity(scene, [a, b])
    one, two = blend_sensitivity(scene, [a]), blend_sensitivity(scene, [b])
    np.testing.assert_allclose(both.weight_sq, one.weight_sq + two.weight_sq, rtol=1e-12)
    assert both.views == 2


def test_default_distribution_surrounds_the_scene_at_three_distances():
    scene = blob_scene(300, seed=2)
    views = default_distribution(scene)
    assert len(views.cameras) == DEFAULT_DIRECTIONS * len(DEFAULT_DISTANCES)
    assert views.source == "default-sphere"
    centres = np.array([c.position for c in views.cameras])
    radii = np.linalg.norm(centres - centres.mean(axis=0), axis=1)
    assert len(np.unique(np.round(radii / radii.min(), 2))) == len(DEFAULT_DISTANCES)
    # Every camera looks at the scene: the centre projects near the image centre.
    for camera in views.cameras:
        p = camera.world_to_camera @ np.append(centres.mean(axis=0), 1.0)
        assert p[2] > 0
        assert abs(camera.fx * p[0] / p[2]) < 2 and abs(camera.fy * p[1] / p[2]) < 2


def test_sphere_directions_are_unit_and_spread():
    d = sphere_directions(64)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert abs(d.mean(axis=0)).max() < 0.05


def test_camera_distribution_caps_count_and_size():
    cameras = [_camera((0.0, 0.0, -4.0 - i), size=(1600, 1200)) for i in range(200)]
    views = camera_distribution(cameras, "cams.json")
    assert len(views.cameras) == 96
    assert max(max(c.width, c.height) for c in views.cameras) == 800
    assert "of 200 cameras from cams.json" in views.description
