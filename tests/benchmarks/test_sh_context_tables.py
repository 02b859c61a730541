"""The context classes and per-class costs of benchmarks/sh_context_tables.py."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.sh_context_tables import channel_costs, context_classes, entropy_bits
from csgs_codec.entropy.histogram import histogram_cost


def test_classes_follow_the_capped_magnitude_of_the_earlier_channels():
    earlier = np.array([[0, 1, -3, 50, 0, 2], [0, 0, 1, -50, 0, 2]])
    classes, count = context_classes(earlier, cap=8, classes=3)
    m = np.array([0, 1, 4, 16, 0, 4])
    assert count == len(np.unique(classes))
    # The class never falls as the context magnitude grows, and equal magnitudes share one.
    order = np.argsort(m, kind="stable")
    assert np.all(np.diff(classes[order]) >= 0)
    assert classes[0] == classes[4] and classes[2] == classes[5]


def test_one_class_costs_the_whole_channel_and_a_revealing_context_costs_less():
    rng = np.random.default_rng(3)
    wide = rng.integers(-6, 7, 4000)
    narrow = np.zeros(4000, np.int64)
    base = np.concatenate([wide, narrow])
    one = channel_costs(base, np.zeros(len(base), np.int64), 1)
    assert one["histogram"] == pytest.approx(histogram_cost(base))
    assert one["ideal"] == pytest.approx(entropy_bits(base))
    split = channel_costs(base, np.repeat([0, 1], 4000), 2)
    assert split["ideal"] == pytest.approx(entropy_bits(wide))  # the zeros cost nothing
    assert split["histogram"] < one["histogram"] and split["frozen"] < one["frozen"]
