"""The allocation benchmark's candidate presets: offsets in octaves and grid bits."""

from __future__ import annotations

import pytest

from benchmarks.allocation import apply
from csgs_codec.decisions.presets import preset


def test_offsets_scale_steps_by_powers_of_two_and_shift_grid_bits():
    base = preset(5)
    moved = apply(base, {"dc_step": 0.5, "opacity_step": -1.0, "position_bits": -1})
    assert moved.dc_step == pytest.approx(base.dc_step * 2**0.5)
    assert moved.opacity_step == pytest.approx(base.opacity_step / 2)
    assert moved.position_bits == base.position_bits - 1
    assert (moved.scale_step, moved.rotation_step, moved.rest_step) == (
        base.scale_step, base.rotation_step, base.rest_step)


def test_no_offsets_is_the_preset():
    assert apply(preset(3), {}) == preset(3)
