"""`csgs view`: offscreen pyvista screenshots show the scene; no display gives a clear error."""

from __future__ import annotations

import ctypes.util
import os

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.render.image_io import load_png
from csgs_codec.render.preview import label_colors
from tests.conftest import SAMPLE
from tests.render.synthetic import blob_scene

HAS_GL = bool(ctypes.util.find_library("EGL") or ctypes.util.find_library("OSMesa")
              or os.environ.get("DISPLAY"))
needs_gl = pytest.mark.skipif(not HAS_GL, reason="no offscreen GL library (libEGL or libOSMesa) "
                              "and no display: install libegl1 libgl1-mesa-dri")


def foreground_fraction(image: np.ndarray) -> float:
    return float((image.max(axis=2) > 0.04).mean())


@needs_gl
def test_screenshot_of_sample_shows_the_donut(tmp_path, capsys):
    out = tmp_path / "donut.png"
    assert main(["view", str(SAMPLE), "--screenshot", str(out), "--size", "200x150",
                 "--max-gaussians", "8000"]) == 0
    image = load_png(out)
    assert image.shape == (150, 200, 3)
    fraction = foreground_fraction(image)
    assert 0.05 < fraction < 0.8  # the donut, centred, with black around it
    rows, cols = np.nonzero(image.max(axis=2) > 0.04)
    assert abs(rows.mean() - 75) < 25 and abs(cols.mean() - 100) < 25
    assert image[image.max(axis=2) > 0.04].std() > 0.05  # icing, dough, sprinkles


@needs_gl
def test_screenshot_in_points_mode(tmp_path):
    path = tmp_path / "blob.ply"
    write_ply(blob_scene(), path)
    out = tmp_path / "points.png"
    assert main(["view", "--quiet", str(path), "--points", "--screenshot", str(out),
                 "--size", "120x90"]) == 0
    assert foreground_fraction(load_png(out)) > 0.01


@needs_gl
def test_screenshot_colors_by_label(tmp_path):
    scene = blob_scene(count=300, labels=np.zeros(300))
    scene.sh_dc[:] = -10  # DC color black: anything visible comes from the label color
    path = tmp_path / "labelled.ply"
    write_ply(scene, path)
    out = tmp_path / "labels.png"
    assert main(["view", "--quiet", str(path), "--screenshot", str(out), "--size", "120x90",
                 "--color", "label"]) == 0
    image = load_png(out)
    lit = image[image.max(axis=2) > 0.04]
    assert len(lit) > 50
    hue = label_colors(np.array([0]))[0]
    brightest = lit[np.argmax(lit.sum(axis=1))]
    np.testing.assert_allclose(brightest / brightest.max(), hue / hue.max(), atol=0.15)


def test_label_colors_are_distinct():
    colors = label_colors(np.arange(12))
    distances = np.linalg.norm(colors[:, None] - colors[None], axis=2)
    assert distances[~np.eye(12, dtype=bool)].min() > 0.05


def test_view_without_display_asks_for_screenshot(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    path = tmp_path / "blob.ply"
    write_ply(blob_scene(count=20), path)
    assert main(["view", str(path)]) == 2
    assert "--screenshot" in capsys.readouterr().err


def test_view_rejects_unsupported_scene_type(tmp_path, capsys):
    path = tmp_path / "scene.obj"
    path.write_bytes(b"v 0 0 0\n")
    assert main(["view", str(path), "--screenshot", str(tmp_path / "x.png")]) == 2
    assert "not supported as input to 'csgs view'" in capsys.readouterr().err
