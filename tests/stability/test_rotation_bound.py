"""The dropped-component bound the stress tests hold rotations to is the true worst case.

Rule: for any unit quaternion and any error of at most e in each of its three stored
smallest-three components, the decoder's dropped component stays within
:func:`dropped_component_bound`, and the bound is reached (it is not loose): about 3e at
(1/2, 1/2, 1/2, 1/2), about e^2 at the identity.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.attributes.attribute_forms import (
    canonical_rotations,
    quaternion_to_smallest_three,
    smallest_three_to_quaternion,
)
from tests.stability.bounds import dropped_component_bound


def _decoded(reference: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """The decoder's quaternions when each stored component (quaternion units) is off by
    ``errors`` (N, 3)."""
    axis, rest = quaternion_to_smallest_three(reference)
    return smallest_three_to_quaternion(axis, rest + errors * np.sqrt(2.0))


def test_no_error_within_e_leaves_the_bound():
    rng = np.random.default_rng(11)
    e = 0.04
    q = canonical_rotations(rng.normal(size=(20000, 4)).astype(np.float32))
    q[:200] = 0.5  # the least precise point
    q[200:400] = (1.0, 0.0, 0.0, 0.0)
    errors = rng.choice([-e, e], size=(len(q), 3)) * rng.uniform(0.5, 1.0, size=(len(q), 1))
    decoded = _decoded(q, errors).astype(np.float64)
    moved = np.abs(decoded[:, 0] - q[:, 0].astype(np.float64))
    bound = dropped_component_bound(q, e)
    assert np.all(moved <= bound)


def test_the_bound_is_reached_at_the_corner_and_tiny_at_the_identity():
    e = 0.04
    corner = np.full((1, 4), 0.5, np.float32)
    worst = _decoded(corner, np.full((1, 3), e))[0, 0]
    bound = dropped_component_bound(corner, e)[0]
    assert abs((0.5 - worst) - bound) < 1e-4 and bound > 2.5 * e
    identity = np.array([[1.0, 0.0, 0.0, 0.0]], np.float32)
    assert dropped_component_bound(identity, e)[0] < 2 * e * e
