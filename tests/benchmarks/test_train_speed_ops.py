"""benchmarks/train_speed.py --count-ops: it counts a stage-1 step's operators by part, and
the step stays within the operator budget that a GPU's step time follows (launch-bound)."""

from __future__ import annotations

import pytest

from benchmarks.train_speed import count_step_ops
from csgs_codec.train.color_stage import initial_state, train_color_stage
from tests.train.stage1_data import tiny_color_settings, tiny_dataset

#: The step's own operators in the form stage 1 takes with gsplat (every slot rendered),
#: rate term on, growth statistics off: rate model 114, spawn 67, bookkeeping 17 when
#: measured (train_speed_ops_2026-11-28.json, 2,000 anchors), 422 before that work. The
#: count does not depend on the scene's size; a change that adds operators to every step
#: shows here.
STEP_BUDGET = 210


@pytest.fixture(scope="module")
def counted():
    data = tiny_dataset()
    settings = tiny_color_settings(iterations=12, rate_start=0.0, growth_start=1.0,
                                   growth_end=1.0, all_slots=True, rasterizer="torch")
    state = initial_state(data.views, data.scene.positions, settings)
    train_color_stage(data.views, state, stop_at=2)
    return count_step_ops(lambda: train_color_stage(data.views, state), 10)


def test_operators_are_counted_by_part_of_the_step(counted):
    parts = counted["by_part"]
    assert {"rate", "scaffold", "step", "rasterizer", "optimizer", "loss"} <= set(parts)
    assert counted["per_step"] == pytest.approx(sum(parts.values()))
    assert 0 < counted["forward_per_step"] < counted["per_step"]
    assert parts["rate"] > 50 and parts["scaffold"] > 30  # forward and backward both seen


def test_the_steps_own_operators_stay_within_budget(counted):
    parts = counted["by_part"]
    own = parts["rate"] + parts["scaffold"] + parts["step"] + parts.get("growth_stats", 0)
    assert own <= STEP_BUDGET, parts
