"""A query's scale does not matter to cosine similarity, so none may break it (issue #52,
item 15): a query of 1e300s overflowed its norm to infinity (NaN scores, an arbitrary
instance chosen), one of subnormals underflowed it to 0."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.scene.instance_table import InstanceTable
from csgs_codec.semantic.query import query_instances
from csgs_codec.semantic.synthetic import labelled_blob_scene

EMBEDDINGS = np.array([[1, 0, 0], [0, 1, 0], [0.6, 0.8, 0]], np.float32)


def _scene():
    scene = labelled_blob_scene(3, 20, seed=1)
    count = int(scene.labels.max()) + 1
    prototypes = np.arange(count * 2, dtype=np.float32).reshape(count, 2)
    embeddings = np.resize(EMBEDDINGS, (count, 3)).astype(np.float32)
    embeddings[3:] *= 0.5  # instances beyond the first three point the same ways, scaled
    return dataclasses.replace(scene, semantic=prototypes[scene.labels],
                               semantic_names=("ins_feat_0", "ins_feat_1"),
                               instances=InstanceTable(prototypes, embeddings))


@pytest.mark.parametrize("scale", [1.0, 1e300, 1e-300, 1e-305])
def test_any_scale_of_a_query_gives_the_same_scores(scale):
    scene = _scene()
    base = np.array([0.1, 1.0, 0.0])
    expected = query_instances(scene, base)
    result = query_instances(scene, base * scale)
    assert np.isfinite(result.scores).all()
    np.testing.assert_allclose(result.scores, expected.scores, rtol=1e-12, atol=1e-15)
    assert result.instance == expected.instance == 1


def test_a_query_that_underflows_to_zero_is_still_refused():
    with pytest.raises(InputError, match="non-zero"):
        query_instances(_scene(), np.array([1e-400, 0.0, 0.0]))
