"""Orbit cameras: aimed at the robust centre, upright, framing the scene, immune to floaters."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.scene.orbit import guess_up_axis, orbit_cameras, parse_up, robust_bounds
from tests.conftest import shared_path
from tests.render.synthetic import blob_scene, project, scene_from


def box_scene(sides, count=2000, seed=0, centre=(0, 0, 0)):
    rng = np.random.default_rng(seed)
    return scene_from(rng.uniform(-0.5, 0.5, size=(count, 3)) * np.asarray(sides)
                      + np.asarray(centre))


def test_orbit_gives_count_views_named_in_order():
    cameras = orbit_cameras(blob_scene(), 16, width=80, height=60)
    assert [c.name for c in cameras] == [f"orbit_{i:03d}" for i in range(16)]
    assert all((c.width, c.height) == (80, 60) for c in cameras)


def test_orbit_cameras_look_at_the_robust_centre():
    scene = box_scene((1, 2, 1), centre=(5, -3, 2))
    low, high = robust_bounds(scene)
    centre = (low + high) / 2
    np.testing.assert_allclose(centre, (5, -3, 2), atol=0.05)
    for camera in orbit_cameras(scene, 8, width=100, height=80, up="+z"):
        np.testing.assert_allclose(project(camera, centre)[0], (50, 40), atol=1e-6)


def test_orbit_cameras_share_distance_and_spread_in_azimuth():
    scene = blob_scene()
    centre = np.mean(robust_bounds(scene), axis=0)
    offsets = [c.position - centre for c in orbit_cameras(scene, 8, up="+z")]
    distances = [np.linalg.norm(o) for o in offsets]
    np.testing.assert_allclose(distances, distances[0], rtol=1e-12)
    azimuths = np.sort([np.arctan2(o[1], o[0]) for o in offsets])
    np.testing.assert_allclose(np.diff(azimuths), 2 * np.pi / 8, atol=1e-9)


@pytest.mark.parametrize("up", ["+z", "-y", "+x", (1.0, 1.0, 0.0)])
def test_orbit_up_points_up_in_the_image(up):
    up_vector = parse_up(up)
    scene = blob_scene()
    middle = np.mean(robust_bounds(scene), axis=0)
    for camera in orbit_cameras(scene, 4, up=up):
        centre, above = project(camera, [middle, middle + 0.1 * up_vector])
        assert above[1] < centre[1] - 1  # smaller pixel row = higher in the image
        assert abs(above[0] - centre[0]) < 1e-6  # and straight above


def test_orbit_frames_the_robust_box_inside_the_image():
    scene = box_scene((2, 1, 1))
    low, high = robust_bounds(scene)
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                        for z in (low[2], high[2])])
    for camera in orbit_cameras(scene, 16, width=200, height=100, up="+z"):
        pixels = project(camera, corners)
        assert np.all((pixels >= 0) & (pixels <= (200, 100)))
        assert np.ptp(pixels[:, 1]) > 30  # and fills a good part of it


def test_orbit_radius_ignores_floaters():
    scene = box_scene((1, 1, 1))
    floaters = scene_from(np.full((10, 3), 1000.0))
    merged = GaussianScene(*(np.concatenate([getattr(scene, f), getattr(floaters, f)])
                             for f in ("positions", "sh_dc", "sh_rest", "opacity", "scales",
                                       "rotations")))
    plain = orbit_cameras(scene, 1, up="+z")[0].position
    noisy = orbit_cameras(merged, 1, up="+z")[0].position
    np.testing.assert_allclose(noisy, plain, atol=0.05)


def test_orbit_bounds_ignore_transparent_gaussians():
    scene = box_scene((1, 1, 1))
    scene.opacity[:1000] = -8.0  # half nearly transparent, spread over a huge box
    scene.positions[:1000] *= 100
    low, high = robust_bounds(scene)
    assert np.all(high - low < 1.1)


def test_guess_up_prefers_thin_axis_for_flat_scenes():
    assert tuple(guess_up_axis(box_scene((1, 1, 0.2)))) == (0, 0, 1)
    assert tuple(guess_up_axis(box_scene((1, 0.2, 1)))) == (0, -1, 0)


def test_guess_up_defaults_to_minus_y_for_captures():
    assert tuple(guess_up_axis(box_scene((0.5, 2, 0.6)))) == (0, -1, 0)


@pytest.mark.parametrize(("name", "up"), [("donut", (0, 0, 1)), ("biker", (0, -1, 0)),
                                          ("playbot", (0, -1, 0)), ("plant", (0, -1, 0))])
def test_guess_up_on_real_scenes(name, up):
    from csgs_codec.interchange.ply_io import read_ply

    path = shared_path("scenes", f"{name}.ply")
    if not path.exists():
        pytest.skip(f"shared data not present: {path}")
    assert tuple(guess_up_axis(read_ply(path))) == up


@pytest.mark.parametrize("bad", ["up", "+w", "", (0, 0, 0), (1, 2)])
def test_parse_up_rejects_bad_axes(bad):
    with pytest.raises(InputError):
        parse_up(bad)


def test_orbit_rejects_empty_scene_and_zero_views():
    with pytest.raises(InputError, match="no Gaussians"):
        orbit_cameras(GaussianScene.empty(), 4)
    with pytest.raises(InputError, match="at least one view"):
        orbit_cameras(blob_scene(), 0)


def test_orbit_of_single_gaussian_is_finite():
    (camera,) = orbit_cameras(scene_from([(1.0, 2.0, 3.0)]), 1)
    assert np.all(np.isfinite(camera.world_to_camera))
    np.testing.assert_allclose(project(camera, (1, 2, 3))[0], (400, 300), atol=1e-6)
