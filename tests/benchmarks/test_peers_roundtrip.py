"""Round-trip comparison of a decoded scene with its original: matching and error figures."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.peers import match_to_original, roundtrip_report
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.scene.gaussian_scene import GaussianScene
from tests.conftest import shared_path


@pytest.fixture(scope="module")
def donut_subset() -> GaussianScene:
    scene = read_ply(shared_path("scenes", "donut.ply"))
    return scene.subset(np.arange(0, len(scene), 97))


def test_identical_scene_is_matched_by_index_with_zero_error(donut_subset):
    report = roundtrip_report(donut_subset, donut_subset)
    assert report["matched_by"] == "index"
    assert report["dropped_gaussians"] == 0
    for key in ("position_max_world", "color_max_rgb01", "opacity_max_alpha",
                "scale_max_logscale", "rotation_max_deg"):
        assert report[key] == pytest.approx(0.0, abs=1e-4), key


def test_reordered_scene_is_matched_by_nearest_position(donut_subset):
    order = np.random.default_rng(3).permutation(len(donut_subset))
    report = roundtrip_report(donut_subset, donut_subset.subset(order))
    assert report["matched_by"] == "nearest_position"
    assert report["unique_match_fraction"] == 1.0
    assert report["color_max_rgb01"] == 0.0
    assert report["scale_max_logscale"] == 0.0


def test_matching_recovers_the_permutation(donut_subset):
    order = np.random.default_rng(4).permutation(len(donut_subset))
    index, method = match_to_original(donut_subset, donut_subset.subset(order))
    assert method == "nearest_position"
    np.testing.assert_array_equal(index, order)


def test_dropped_gaussians_are_counted(donut_subset):
    report = roundtrip_report(donut_subset, donut_subset.subset(np.arange(10, len(donut_subset))))
    assert report["dropped_gaussians"] == 10
    assert report["decoded_gaussians"] == len(donut_subset) - 10


def test_position_error_is_measured_in_world_units(donut_subset):
    moved = donut_subset.subset(np.arange(len(donut_subset)))
    moved.positions = moved.positions + np.float32(1e-5)
    report = roundtrip_report(donut_subset, moved)
    assert report["matched_by"] == "index"
    assert report["position_max_world"] == pytest.approx(1e-5, rel=0.05)


def test_negated_quaternion_counts_as_no_rotation_error(donut_subset):
    flipped = donut_subset.subset(np.arange(len(donut_subset)))
    flipped.rotations = -flipped.rotations
    assert roundtrip_report(donut_subset, flipped)["rotation_max_deg"] < 0.05


def test_invisible_gaussians_are_left_out_of_visible_errors(donut_subset):
    changed = donut_subset.subset(np.arange(len(donut_subset)))
    invisible = 1 / (1 + np.exp(-donut_subset.opacity)) < 1 / 255
    assert invisible.any()
    changed.sh_dc[invisible] = -3.0
    report = roundtrip_report(donut_subset, changed)
    assert report["color_max_rgb01"] > 0.1
    assert report["visible_only"]["color_max_rgb01"] == 0.0
    assert report["visible_gaussians"] == int((~invisible).sum())
