"""`csgs view --select X,Y | --select-mask M.npy`: the selection keeps its color, the rest
is drawn dim."""

from __future__ import annotations

import ctypes.util
import os

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.render.image_io import load_png
from csgs_codec.render.preview import UNSELECTED_SHADE, highlight_selection, preview_camera
from csgs_codec.semantic.synthetic import labelled_blob_scene
from tests.semantic.scenes import centre_pixel

HAS_GL = bool(ctypes.util.find_library("EGL") or ctypes.util.find_library("OSMesa")
              or os.environ.get("DISPLAY"))
needs_gl = pytest.mark.skipif(not HAS_GL, reason="no offscreen GL library and no display")
SIZE = (160, 120)
#: Up axis of the preview: the two objects, spaced along x, appear one above the other.
UP = "+x"


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    scene = labelled_blob_scene(2, 300, seed=2, spacing=1.2)
    scene.sh_dc[:] = 1.5  # both objects bright white: only the selection changes brightness
    path = tmp_path_factory.mktemp("view") / "two.ply"
    write_ply(scene, path)
    return scene, path


def test_highlight_keeps_selected_colors_and_dims_the_rest():
    colors = np.array([[0.9, 0.3, 0.3], [0.6, 0.6, 0.6]], np.float32)
    out = highlight_selection(colors, np.array([True, False]))
    np.testing.assert_allclose(out[0], colors[0])
    np.testing.assert_allclose(out[1], [UNSELECTED_SHADE * 0.6] * 3, rtol=1e-6)


def test_highlight_rejects_a_mask_of_the_wrong_shape():
    with pytest.raises(InputError, match="selection mask"):
        highlight_selection(np.zeros((3, 3), np.float32), np.ones(2, bool))


def brightness_near(image, point) -> float:
    x, y = int(point[0]), int(point[1])
    return float(image[max(y - 3, 0):y + 4, max(x - 3, 0):x + 4].mean())


@needs_gl
def test_view_select_highlights_the_clicked_object(labelled, tmp_path):
    scene, path = labelled
    camera = preview_camera(scene, SIZE, UP)
    first, second = centre_pixel(scene, camera, 0), centre_pixel(scene, camera, 1)
    out = tmp_path / "select.png"
    assert main(["view", "-q", str(path), "--screenshot", str(out), "--points", "--size",
                 f"{SIZE[0]}x{SIZE[1]}", "--up", UP, "--color", "dc", "--select",
                 f"{first[0]:.1f},{first[1]:.1f}"]) == 0
    image = load_png(out)
    assert brightness_near(image, first) > 2 * brightness_near(image, second) > 0


@needs_gl
def test_view_select_mask_highlights_the_masked_object(labelled, tmp_path):
    scene, path = labelled
    mask_path = tmp_path / "mask.npy"
    np.save(mask_path, scene.labels == 1)
    camera = preview_camera(scene, SIZE, UP)
    out = tmp_path / "mask.png"
    assert main(["view", "-q", str(path), "--screenshot", str(out), "--points", "--size",
                 f"{SIZE[0]}x{SIZE[1]}", "--up", UP, "--color", "dc", "--select-mask",
                 str(mask_path)]) == 0
    image = load_png(out)
    first, second = centre_pixel(scene, camera, 0), centre_pixel(scene, camera, 1)
    assert brightness_near(image, second) > 2 * brightness_near(image, first) > 0


@pytest.mark.parametrize("mask", [np.ones(5, bool), np.ones(600, np.int32), None])
def test_view_rejects_a_mask_that_does_not_fit(labelled, tmp_path, capsys, mask):
    _, path = labelled
    mask_path = tmp_path / "mask.npy"
    if mask is None:
        mask_path.write_bytes(b"not a numpy file")
    else:
        np.save(mask_path, mask)
    assert main(["view", str(path), "--screenshot", str(tmp_path / "o.png"),
                 "--select-mask", str(mask_path)]) == 2
    assert "selection mask" in capsys.readouterr().err
    assert not (tmp_path / "o.png").exists()


def test_view_select_on_the_background_exits_2(labelled, tmp_path, capsys):
    _, path = labelled
    assert main(["view", str(path), "--screenshot", str(tmp_path / "o.png"), "--size",
                 "160x120", "--select", "1,1"]) == 2
    assert "nothing under the click" in capsys.readouterr().err
