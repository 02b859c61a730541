"""Stress scenes through the color codec: exact decode, no NaN, error within the bounds.

Each stress scene (tests/stability/stress_scenes.py) is encoded at quality 1, 5 and 9 (the
plain scene at every quality 1..9; the rest of the matrix is `slow`). The rules: the decode
equals the encoder's reconstruction bit for bit, holds no NaN or Inf, and stays within the
bounds of the steps used (tests/stability/bounds.py); degenerate scenes decode as described
by the test names.
"""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.attribute_forms import canonical_orientations
from csgs_codec.attributes.float_stream import MAX_FRAC_BITS
from csgs_codec.decisions.presets import PRESETS, preset
from tests.stability.bounds import (
    assert_all_finite,
    assert_within_bounds,
    coded_orientations,
    result_steps,
    rotation_component_error,
    snapped_step,
)
from tests.stability.round_trips import stress_round_trip
from tests.stability.stress_scenes import STRESS_SCENES

#: Qualities every stress scene runs at by default (the plain scene runs all nine); the other
#: (scene, quality) pairs are `slow`.
DEFAULT_QUALITIES = (1, 5, 9)
CASES = [pytest.param(name, q, id=f"{name}-q{q}",
                      marks=[] if q in DEFAULT_QUALITIES or name == "plain"
                      else [pytest.mark.slow])
         for name in STRESS_SCENES for q in sorted(PRESETS)]


@pytest.mark.parametrize(("name", "quality"), CASES)
def test_decode_equals_the_encoders_reconstruction_bit_for_bit(name, quality):
    trip = stress_round_trip(name, quality)
    assert trip.decoded.equals(trip.result.reconstruction)


@pytest.mark.parametrize(("name", "quality"), CASES)
def test_decoded_scene_holds_no_nan_or_inf(name, quality):
    assert_all_finite(stress_round_trip(name, quality).decoded)


@pytest.mark.parametrize(("name", "quality"), CASES)
def test_decoded_scene_stays_within_the_bounds_of_its_steps(name, quality):
    trip = stress_round_trip(name, quality)
    assert_within_bounds(trip.decoded, trip.reference, result_steps(trip.result, preset(quality)),
                         sorted_axes=trip.result.sorted_axes)


@pytest.mark.parametrize("quality", [1, 9])
def test_opacity_logits_beyond_ten_decode_near_the_clamp(quality):
    trip = stress_round_trip("opacity_logits_1e4", quality)
    huge = trip.reference.opacity == 1e4
    tiny = trip.reference.opacity == -1e4
    assert huge.any() and tiny.any()
    step = result_steps(trip.result, preset(quality)).steps["opacity"]
    margin = snapped_step(step, MAX_FRAC_BITS) / 2 + 1e-6
    assert np.all(np.abs(trip.decoded.opacity[huge] - 10.0) <= margin)
    assert np.all(np.abs(trip.decoded.opacity[tiny] + 10.0) <= margin)


def test_identical_gaussians_decode_exactly():
    trip = stress_round_trip("identical_gaussians", 1)
    ref, dec = trip.reference, trip.decoded
    for name in ("positions", "sh_dc", "sh_rest", "opacity"):
        np.testing.assert_array_equal(getattr(dec, name), getattr(ref, name), err_msg=name)
    rotations, scales = coded_orientations(ref, trip.result.sorted_axes)
    np.testing.assert_array_equal(dec.scales, scales)
    np.testing.assert_allclose(dec.rotations, rotations, atol=1e-6)
    assert np.all(dec.rotations == dec.rotations[:1])


def test_identical_gaussians_spend_no_bytes_per_gaussian():
    one = stress_round_trip("n1", 5).result.data
    many = stress_round_trip("identical_gaussians", 5).result.data
    assert len(many) < len(one) + 64


def test_empty_scene_decodes_empty_with_its_sh_degree():
    trip = stress_round_trip("n0", 5)
    assert len(trip.decoded) == 0
    assert trip.decoded.sh_degree_stored == 3
    assert trip.decoded.sh_rest.shape == (0, 15, 3)


def test_single_gaussian_decodes_exactly_but_its_rotation_normalised():
    trip = stress_round_trip("n1", 5)
    ref, dec = trip.reference, trip.decoded
    for name in ("positions", "sh_dc", "sh_rest", "opacity"):
        np.testing.assert_array_equal(getattr(dec, name), getattr(ref, name), err_msg=name)
    rotations, scales = coded_orientations(ref, trip.result.sorted_axes)
    np.testing.assert_array_equal(dec.scales, scales)
    np.testing.assert_allclose(dec.rotations, rotations, atol=1e-6)


def test_zero_quaternions_decode_as_the_identity():
    quality = 9
    trip = stress_round_trip("unnormalised_zero_quaternions", quality)
    zero = ~np.any(trip.reference.rotations != 0, axis=1)
    assert zero.sum() >= 10
    step = result_steps(trip.result, preset(quality)).steps["rot"]
    tolerance = 3 * rotation_component_error(step)
    # The identity, in the form the encoder codes it (axes sorted by scale: the same Gaussian).
    identity = np.tile(np.float32([1.0, 0.0, 0.0, 0.0]), (int(zero.sum()), 1))
    expected, _ = (canonical_orientations(identity, trip.reference.scales[zero])
                   if trip.result.sorted_axes else (identity, None))
    np.testing.assert_allclose(trip.decoded.rotations[zero], expected, rtol=0, atol=tolerance)


def test_unnormalised_quaternions_decode_to_unit_length():
    trip = stress_round_trip("unnormalised_zero_quaternions", 5)
    norms = np.linalg.norm(trip.decoded.rotations.astype(np.float64), axis=1)
    np.testing.assert_allclose(norms, 1.0, rtol=0, atol=1e-6)


def test_duplicate_positions_stay_duplicates():
    trip = stress_round_trip("duplicate_positions", 5)
    ref, dec = trip.reference.positions, trip.decoded.positions
    _, groups = np.unique(ref, axis=0, return_inverse=True)
    groups = groups.reshape(-1)
    assert np.bincount(groups).max() == 8
    for g in np.unique(groups):
        assert np.all(dec[groups == g] == dec[groups == g][0])


@pytest.mark.parametrize("name", ["far_outlier_1e7", "far_outlier_3e38", "far_outlier_among_49"])
def test_far_outlier_is_kept_exactly_without_coarsening_the_grid(name):
    quality = 5
    trip = stress_round_trip(name, quality)
    assert "OUTL" in trip.result.stream_bytes
    far = np.abs(trip.reference.positions).max(axis=1) > 1e6
    assert far.sum() == 1
    assert np.all(trip.decoded.positions[far] == trip.reference.positions[far])
    # The dense unit cube keeps the resolution it would have without the outlier.
    bits = result_steps(trip.result, preset(quality)).position_bits
    cell = 1.0 / (2**bits - 1)
    error = np.abs(trip.decoded.positions[~far] - trip.reference.positions[~far]).max()
    assert error <= cell


@pytest.mark.parametrize(("name", "extent"),
                         [("extent_1e-6", 1e-6), ("extent_1e6", 1e6), ("extent_1_at_1e5", 1.0)])
def test_position_error_scales_with_the_extent(name, extent):
    quality = 5
    trip = stress_round_trip(name, quality)
    ref = trip.reference.positions
    relative = np.abs(trip.decoded.positions.astype(np.float64) - ref) / extent
    # Half a cell of at most extent / (2^bits - 1), plus float32 rounding far from the origin.
    float32_rounding = float(np.spacing(np.float32(np.abs(ref).max()))) / extent
    bits = result_steps(trip.result, preset(quality)).position_bits
    assert relative.max() <= 0.5 / (2**bits - 1) + float32_rounding
