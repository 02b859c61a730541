"""Hand-computed renders: one Gaussian's peak and footprint, depth order, stop rules.

Every test runs on each CPU backend (torch reference and numba), so both obey the rules.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.projection import LOW_PASS_VARIANCE
from csgs_codec.render.rasterizer import render
from tests.render.test_raster_common import camera_at_origin, gaussians

BACKENDS = ["torch", pytest.param("numba", marks=pytest.mark.skipif(
    not numba_available(), reason="numba not installed"))]

FOCAL, SIGMA, DEPTH = 40.0, 0.1, 2.0
#: Screen variance of the test Gaussian: (f sigma / z)^2 + 0.3 = 4.3 px^2.
VARIANCE = (FOCAL * SIGMA / DEPTH) ** 2 + LOW_PASS_VARIANCE
RED, GREEN, BLUE = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _logit(p: float) -> float:
    return math.log(p / (1 - p))


@pytest.mark.parametrize("backend", BACKENDS)
def test_single_gaussian_peak_is_opacity_times_color(backend):
    cam = camera_at_origin(focal=FOCAL)
    scene = gaussians([0, 0, DEPTH], [1.0, 0.5, 0.25], math.log(SIGMA), _logit(0.5))
    out = render(scene, cam, backend=backend)
    row, col = cam.height // 2, cam.width // 2
    np.testing.assert_allclose(out.image[row, col], [0.5, 0.25, 0.125], atol=1e-6)
    assert out.alpha[row, col] == pytest.approx(0.5, abs=1e-6)
    assert out.depth[row, col] == pytest.approx(DEPTH, abs=1e-5)
    # Three pixels right of the peak: 0.5 * exp(-0.5 * 9 / 4.3).
    expected = 0.5 * math.exp(-0.5 * 9 / VARIANCE)
    assert out.alpha[row, col + 3] == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_single_gaussian_footprint_ends_where_alpha_drops_below_1_over_255(backend):
    cam = camera_at_origin(focal=FOCAL)
    scene = gaussians([0, 0, DEPTH], [1.0, 1.0, 1.0], math.log(SIGMA), _logit(0.5))
    out = render(scene, cam, backend=backend)
    # 0.5 exp(-r^2 / (2 * 4.3)) >= 1/255  <=>  r^2 <= 2 * 4.3 * ln(127.5) = 41.7 px^2.
    limit = 2 * VARIANCE * math.log(0.5 * 255)
    rows, cols = np.indices((cam.height, cam.width))
    r2 = (rows - cam.height // 2) ** 2 + (cols - cam.width // 2) ** 2
    assert np.array_equal(out.alpha > 0, r2 <= limit)
    assert (out.alpha[r2 <= limit] >= 1 / 255 - 1e-7).all()


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_gaussians_composite_front_to_back_in_depth_order(backend):
    cam = camera_at_origin(focal=FOCAL)
    row, col = cam.height // 2, cam.width // 2
    # Listed far first: the rasterizer must sort by depth, not by index.
    scene = gaussians([[0, 0, 3.0], [0, 0, 2.0]], [GREEN, RED], math.log(SIGMA), _logit(0.5))
    out = render(scene, cam, backend=backend, background=(0.0, 0.0, 1.0))
    np.testing.assert_allclose(out.image[row, col], [0.5, 0.25, 0.25], atol=1e-6)
    assert out.alpha[row, col] == pytest.approx(0.75, abs=1e-6)
    assert out.depth[row, col] == pytest.approx((0.5 * 2 + 0.25 * 3) / 0.75, abs=1e-5)
    swapped = gaussians([[0, 0, 3.0], [0, 0, 2.0]], [RED, GREEN], math.log(SIGMA),
                        _logit(0.5))
    np.testing.assert_allclose(render(swapped, cam, backend=backend).image[row, col],
                               [0.25, 0.5, 0.0], atol=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_features_are_composited_with_the_color_weights(backend):
    cam = camera_at_origin(focal=FOCAL)
    scene = gaussians([[0, 0, 2.0], [0, 0, 3.0]], [RED, GREEN], math.log(SIGMA), _logit(0.5))
    feats = np.array([[1.0, 0.0], [0.0, 2.0]], np.float32)
    out = render(scene, cam, backend=backend, features=feats)
    assert out.features.shape == (cam.height, cam.width, 2)
    np.testing.assert_allclose(out.features[cam.height // 2, cam.width // 2], [0.5, 0.5],
                               atol=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_alpha_is_clamped_to_0_99_and_compositing_stops_below_transmittance_1e4(backend):
    cam = camera_at_origin(focal=FOCAL)
    row, col = cam.height // 2, cam.width // 2
    pos = [[0, 0, 2.0], [0, 0, 3.0], [0, 0, 4.0]]
    scene = gaussians(pos, [RED, GREEN, BLUE], math.log(SIGMA), 12.0)
    scene.opacity[1] = _logit(0.9)
    out = render(scene, cam, backend=backend)
    # T: 1 -> 0.01 (alpha clamped to 0.99) -> 0.001; the third would take T to 1e-5 < 1e-4,
    # so it is skipped and compositing stops.
    np.testing.assert_allclose(out.image[row, col], [0.99, 0.009, 0.0], atol=1e-6)
    assert out.alpha[row, col] == pytest.approx(0.999, abs=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_gaussians_behind_the_near_plane_are_not_drawn(backend):
    cam = camera_at_origin(focal=FOCAL)
    scene = gaussians([[0, 0, -2.0], [0, 0, 0.005]], [RED, GREEN], math.log(SIGMA), 3.0)
    out = render(scene, cam, backend=backend)
    assert not out.alpha.any() and not out.image.any()


@pytest.mark.parametrize("backend", BACKENDS)
def test_background_fills_uncovered_pixels(backend):
    cam = camera_at_origin(focal=FOCAL)
    scene = gaussians([0, 0, DEPTH], [RED], math.log(SIGMA), _logit(0.5))
    out = render(scene, cam, backend=backend, background=(0.2, 0.4, 0.6))
    np.testing.assert_allclose(out.image[0, 0], [0.2, 0.4, 0.6], atol=1e-7)
    assert out.depth[0, 0] == 0.0
