"""Recolouring a view from its recorded blending weights (csgs_codec/render/blend_record.py)
gives, bit for bit, the image a full numba render of the recoloured scene gives."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.render.blend_record import render_recording
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.rasterizer import render
from tests.codec.helpers import random_scene
from tests.conftest import SAMPLE
from tests.render.test_raster_common import look_at_camera, orbit_view

pytestmark = pytest.mark.skipif(not numba_available(), reason="numba not installed")


def _recoloured(scene, seed: int):
    rng = np.random.default_rng(seed)
    other = scene.subset(np.arange(len(scene)))
    other.sh_dc = (scene.sh_dc + rng.normal(0.0, 0.3, scene.sh_dc.shape)).astype(np.float32)
    other.sh_rest = (scene.sh_rest * rng.uniform(0.0, 2.0, scene.sh_rest.shape)
                     ).astype(np.float32)
    return other


@pytest.mark.parametrize("sh_degree, background", [(3, (0.0, 0.0, 0.0)), (1, (0.2, 0.5, 0.9))])
def test_a_recoloured_view_is_the_render_of_the_recoloured_scene(sh_degree, background):
    scene = random_scene(2000, sh_degree=sh_degree, seed=sh_degree)
    camera = look_at_camera(np.array([0.3, -0.8, -3.0]), np.zeros(3),
                            np.array([0.0, -1.0, 0.0]), 96, 72)
    image, record = render_recording(scene, camera, background=background)
    np.testing.assert_array_equal(image, render(scene, camera, backend="numba",
                                                background=background).image)
    for seed in range(3):
        other = _recoloured(scene, seed)
        expected = render(other, camera, backend="numba", background=background).image
        np.testing.assert_array_equal(record.recolour(other), expected)
    assert record.ids.dtype == np.int32 and record.weights.dtype == np.float32
    assert len(record.ids) == int(record.counts.sum()) == record.starts[-1]


def test_the_samples_view_recolours_exactly_and_the_record_keeps_only_blended_pairs():
    scene = read_ply(SAMPLE)
    camera = orbit_view(scene, [0, 0, 1], 120, 90, azimuth_deg=30)
    image, record = render_recording(scene, camera)
    assert (1.0 - record.transmittance).max() > 0.5, "the view must show the sample"
    other = _recoloured(scene, 7)
    np.testing.assert_array_equal(record.recolour(other),
                                  render(other, camera, backend="numba").image)
    # Every pair kept has a weight the compositing added (alpha T >= T_stop / 255 > 0).
    assert record.weights.min() > 0.0
    assert record.nbytes == sum(a.nbytes for a in (record.starts, record.counts, record.ids,
                                                   record.weights, record.transmittance))


def test_a_view_over_the_slot_budget_is_rendered_without_a_record():
    scene = random_scene(500, sh_degree=0, seed=4)
    camera = look_at_camera(np.array([0.0, 0.0, -3.0]), np.zeros(3),
                            np.array([0.0, -1.0, 0.0]), 64, 48)
    image, record = render_recording(scene, camera, max_slots=10)
    assert record is None
    np.testing.assert_array_equal(image, render(scene, camera, backend="numba").image)
