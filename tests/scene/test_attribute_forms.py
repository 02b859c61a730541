"""Coding forms: smallest-three rotations, opacity clamping, and the position grid."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from csgs_codec.attributes.attribute_forms import (
    clamp_opacity_logits,
    normalize_quaternions,
    quaternion_to_smallest_three,
    smallest_three_to_quaternion,
)
from csgs_codec.attributes.position_grid import MAX_BITS, PositionGrid
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply
from tests.conftest import SAMPLE

finite = st.floats(-1e3, 1e3, allow_nan=False, width=32)


def same_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|<a, b>| per row: 1 when the quaternions give the same rotation."""
    return np.abs(np.sum(a.astype(np.float64) * b, axis=1))


@settings(max_examples=200, deadline=None)
@given(arrays(np.float32, (16, 4), elements=finite))
def test_smallest_three_round_trip_is_the_same_rotation(q):
    largest, rest = quaternion_to_smallest_three(q)
    assert rest.min() >= -1 and rest.max() <= 1
    back = smallest_three_to_quaternion(largest, rest)
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), 1.0, atol=1e-6)
    assert np.all(same_rotation(back, normalize_quaternions(q)) > 1 - 1e-6)


def test_zero_quaternion_becomes_identity():
    q = np.zeros((2, 4), np.float32)
    q[1] = (0, 0, 0, -3)
    largest, rest = quaternion_to_smallest_three(q)
    back = smallest_three_to_quaternion(largest, rest)
    np.testing.assert_array_equal(back[0], [1, 0, 0, 0])
    np.testing.assert_array_equal(back[1], [0, 0, 0, 1])


def test_quantized_smallest_three_error_is_bounded_for_every_component():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(20000, 4)).astype(np.float32)
    largest, rest = quaternion_to_smallest_three(q)
    step = 2.0 / 255
    back = smallest_three_to_quaternion(largest, (np.rint(rest / step) * step).astype(np.float32))
    # Each kept component errs by <= step / (2 sqrt 2); the largest by a bounded amount too.
    assert np.max(np.abs(back - normalize_quaternions(q) *
                         np.sign(np.take_along_axis(normalize_quaternions(q),
                                                    largest[:, None].astype(int), 1)))) < 0.01


def test_smallest_three_decode_is_deterministic_float32():
    rest = np.array([[0.5, -0.25, 0.125]], np.float32)
    out = smallest_three_to_quaternion(np.array([2]), rest)
    c = rest / np.float32(np.sqrt(2.0))
    expected_big = np.sqrt(np.float32(1) - ((c[0, 0] * c[0, 0] + c[0, 1] * c[0, 1])
                                            + c[0, 2] * c[0, 2]))
    assert out.dtype == np.float32 and out[0, 2] == expected_big
    assert out[0, 0] == c[0, 0] and out[0, 3] == c[0, 2]


def test_opacity_clamp():
    out = clamp_opacity_logits(np.array([-1e4, -3, 0, 12], np.float32))
    np.testing.assert_array_equal(out, [-10, -3, 0, 10])


def test_grid_error_is_at_most_half_a_cell_on_a_real_scene():
    scene = read_ply(SAMPLE)
    grid = PositionGrid.fit(scene.positions, 16)
    cells, inside = grid.quantize(scene.positions)
    assert inside.all() and cells.max() < 2**grid.bits
    err = np.abs(grid.dequantize(cells) - scene.positions)
    assert err.max() <= grid.max_error


def test_far_floater_does_not_coarsen_the_grid():
    rng = np.random.default_rng(2)
    p = rng.uniform(0, 1, size=(5000, 3))
    p[0] = (1e7, 0, 0)
    grid = PositionGrid.fit(p, 12)
    assert grid.cell == pytest.approx(0.98 / 4095, rel=0.05)
    assert grid.bits == MAX_BITS
    cells, inside = grid.quantize(p)
    assert not inside[0] and inside[1:].all()
    assert np.abs(grid.dequantize(cells[1:]) - p[1:]).max() <= grid.max_error


def test_moderate_outlier_widens_the_grid_instead():
    p = np.random.default_rng(3).uniform(0, 1, size=(1000, 3))
    p[0] = (50, 0, 0)
    grid = PositionGrid.fit(p, 10)
    assert grid.bits == 16 and grid.quantize(p)[1].all()


def test_degenerate_positions():
    assert PositionGrid.fit(np.zeros((0, 3)), 10).bits == 1
    same = np.ones((7, 3))
    grid = PositionGrid.fit(same, 10)
    cells, inside = grid.quantize(same)
    assert inside.all()
    np.testing.assert_array_equal(grid.dequantize(cells), same.astype(np.float32))


def test_grid_rejects_bad_arguments():
    with pytest.raises(InputError):
        PositionGrid.fit(np.zeros((3, 3)), 0)
    with pytest.raises(InputError, match="finite"):
        PositionGrid.fit(np.array([[np.nan, 0, 0]]), 8)
