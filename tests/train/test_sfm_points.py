"""Initial points triangulated by pycolmap from views with known poses (issue #31 item 3)."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
import pytest

from csgs_codec.errors import CsgsWarning
from csgs_codec.metrics.attribute_errors import nearest_neighbours
from csgs_codec.train.initial_points import RANDOM_POINT_COUNT, find_initial_points
from csgs_codec.train.sfm_points import (
    cached_points,
    pycolmap_available,
    triangulate_views,
    views_key,
)
from csgs_codec.train.synthetic import write_transforms_dataset
from csgs_codec.train.views import TrainingView

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "donut.ply"
needs_pycolmap = pytest.mark.skipif(not pycolmap_available(), reason="needs pycolmap")


@pytest.fixture(scope="module")
def capture():
    """24 renders at 320x240 of the sample (a real trained scene) around an orbit: its
    images and cameras, and the scene whose Gaussians the points should lie on."""
    from csgs_codec.interchange.ply_io import read_ply
    from csgs_codec.render.rasterizer import render
    from csgs_codec.scene.orbit import orbit_cameras

    scene = read_ply(SAMPLE)
    views = []
    for camera in orbit_cameras(scene, 24, width=320, height=240):
        image = np.clip(render(scene, camera, backend="numba").image, 0, 1)
        views.append(TrainingView(image.astype(np.float32), camera, name=f"{camera.name}.png"))
    return scene, views


@needs_pycolmap
def test_points_triangulated_at_known_poses_lie_on_the_scene(capture, tmp_path):
    scene, views = capture
    found = triangulate_views(views, cache=tmp_path)
    assert not found.cached and len(found.points) >= 150  # 294 measured
    _, distance = nearest_neighbours(found.points, scene.positions.astype(np.float64))
    extent = float(np.ptp(scene.positions, axis=0).max())
    # Points land on the scene's surface: most within 1% of its extent of a Gaussian.
    assert np.median(distance) < 0.01 * extent
    again = triangulate_views(views, cache=tmp_path)
    assert again.cached and np.array_equal(again.points, found.points)
    assert found.folder.name == views_key(views)


@needs_pycolmap
def test_a_capture_without_points_starts_from_triangulated_ones(capture, tmp_path,
                                                                monkeypatch):
    _, views = capture
    monkeypatch.setenv("CSGS_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "data"
    write_transforms_dataset(views, folder)
    points, source = find_initial_points(folder, [v.camera for v in views], views=views)
    assert "triangulated by pycolmap" in source and len(points) >= 150


def test_without_views_random_points_come_with_a_warning(capture, tmp_path):
    _, views = capture
    write_transforms_dataset(views[:2], tmp_path)
    with pytest.warns(CsgsWarning, match="random points"):
        points, source = find_initial_points(tmp_path, [v.camera for v in views[:2]])
    assert len(points) == RANDOM_POINT_COUNT and "random" in source


@needs_pycolmap
def test_a_damaged_cache_is_warned_about_once_and_triangulated_again(capture, tmp_path):
    # issue #52 item 9: a truncated points.npy made every later train of the dataset die
    _, views = capture
    views = views[:6]  # 6 neighbouring views: enough to triangulate, quick
    stored = tmp_path / views_key(views) / "points.npy"
    stored.parent.mkdir(parents=True)
    buffer = io.BytesIO()
    np.save(buffer, np.ones((100, 3)))
    stored.write_bytes(buffer.getvalue()[:200])  # cut short, as by a crash mid-write
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = triangulate_views(views, cache=tmp_path)
    damaged = [w for w in caught if "damaged triangulation cache" in str(w.message)]
    assert len(damaged) == 1 and str(stored) in str(damaged[0].message)
    assert not found.cached and len(found.points) > 0
    again = triangulate_views(views, cache=tmp_path)
    assert again.cached and np.array_equal(again.points, found.points)


@pytest.mark.parametrize("content", [b"", b"\x93NUMPY\x01\x00", b"not numpy at all"])
def test_cached_points_ignore_a_damaged_file_with_a_warning(tmp_path, content):
    stored = tmp_path / "points.npy"
    stored.write_bytes(content)
    with pytest.warns(CsgsWarning, match="damaged triangulation cache"):
        assert cached_points(stored) is None
