"""The encoder's voxel grid: inferred from anchors on a grid, a fallback grid otherwise."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.anchor_grid import FALLBACK_BITS, anchor_grid
from csgs_codec.errors import InputError


def test_anchors_on_a_voxel_grid_give_that_grid():
    rng = np.random.default_rng(0)
    cells = rng.integers(0, 300, (2000, 3))
    positions = (np.array([-1.25, 0.5, 3.0]) + cells * 0.01).astype(np.float32)
    grid = anchor_grid(positions)
    assert grid.voxel_size == pytest.approx(0.01, rel=1e-5)
    assert np.array_equal(grid.cells, cells - cells.min(axis=0))
    assert np.abs(grid.positions() - positions).max() <= 1e-6


def test_anchors_off_any_grid_get_the_fallback_grid_within_half_a_cell():
    positions = np.random.default_rng(1).uniform(-2, 2, (500, 3)).astype(np.float32)
    grid = anchor_grid(positions)
    assert grid.bits == FALLBACK_BITS
    assert np.abs(grid.positions() - positions).max() <= grid.voxel_size / 2 + 1e-6


@pytest.mark.parametrize("voxel", [0.0, -1.0, float("nan"), 1e-9])
def test_a_bad_voxel_size_is_an_input_error(voxel):
    positions = np.random.default_rng(1).uniform(-2, 2, (50, 3)).astype(np.float32)
    with pytest.raises(InputError):
        anchor_grid(positions, voxel)
