"""Property-based sweep: scenes mixing every stress round-trip exactly and within bounds.

Rule: for any mixed stress scene (tests/stability/mixed_scenes.py) and quality, the decode
equals the encoder's reconstruction bit for bit, holds no NaN or Inf, and stays within the
bounds of the steps used (tests/stability/bounds.py). A few examples run by default; the
`slow` sweep runs hundreds, with larger scenes.
"""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgs_codec.decisions.presets import preset
from tests.stability.bounds import assert_all_finite, assert_within_bounds, result_steps
from tests.stability.mixed_scenes import mixed_scene
from tests.stability.round_trips import round_trip

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)


def _check(seed: int, n: int, sh_degree: int, quality: int) -> None:
    trip = round_trip(mixed_scene(seed, n, sh_degree), quality)
    assert trip.decoded.equals(trip.result.reconstruction)
    assert_all_finite(trip.decoded)
    assert_within_bounds(trip.decoded, trip.reference, result_steps(trip.result, preset(quality)),
                         sorted_axes=trip.result.sorted_axes)


@settings(max_examples=12, **SETTINGS)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 200), sh_degree=st.integers(0, 3),
       quality=st.integers(1, 9))
def test_mixed_stress_scenes_round_trip_within_bounds(seed, n, sh_degree, quality):
    _check(seed, n, sh_degree, quality)


@pytest.mark.slow
@settings(max_examples=300, **SETTINGS)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 20000), sh_degree=st.integers(0, 3),
       quality=st.integers(1, 9))
def test_mixed_stress_scenes_round_trip_within_bounds_slow(seed, n, sh_degree, quality):
    _check(seed, n, sh_degree, quality)
